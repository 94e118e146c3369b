# MuJoCo backend extras (issue 5). With sim.backend: mujoco and sim.mujoco.render_clips: true,
# one GIF per (study, run) of `all` — the smallest N, first seed — rendered offscreen from the evaluation
# job's trajectory and logged to MLflow; without a GL context the job records why and succeeds.
if BACKEND == "mujoco" and config["sim"]["mujoco"]["render_clips"]:

    rule render_clip:
        input:
            tracking=TRACKING,
            traj=f"{RESULTS}/eval/{{backend}}/{{study}}/{{run}}/n{{n}}_seed{{seed}}_traj.npz",
        output:
            f"{RESULTS}/clips/{{backend}}/{{study}}/{{run}}/n{{n}}_seed{{seed}}.json",
        params:
            config=RESOLVED,
            settings=settings_hash("render-clip"),
            source=source_hash("render-clip"),
        resources:
            mem_mb=2000,
            runtime=15,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/render_clip/{{backend}}/{{study}}/{{run}}/n{{n}}_seed{{seed}}.log",
        shell:
            "python -m madpinn render-clip --config {params.config:q} --traj {input.traj:q} --out {output:q}"
            " --key {wildcards.backend:q}/{wildcards.study:q}/{wildcards.run:q}/n{wildcards.n}_seed{wildcards.seed} 2>&1 | tee {log:q}"

    register_targets(*[
        f"{RESULTS}/clips/{study_backend(config, study)}/{study}/{run}/n{min(st['agent_counts'])}_seed{st['seeds'][0]}.json"
        for study, st in ((s, config["studies"][s]) for s in studies_in_all())
        for run in st["runs"]
    ])
