# One job per (backend, study, run, N, seed) cell: per-scenario Parquet, JSON summary, and the
# first scenario's trajectory; then one MLflow run.
rule evaluate:
    input:
        unpack(run_models),
        tracking=TRACKING,
    output:
        parquet=f"{RESULTS}/eval/{{backend}}/{{study}}/{{run}}/n{{n}}_seed{{seed}}.parquet",
        summary=f"{RESULTS}/eval/{{backend}}/{{study}}/{{run}}/n{{n}}_seed{{seed}}.json",
        traj=f"{RESULTS}/eval/{{backend}}/{{study}}/{{run}}/n{{n}}_seed{{seed}}_traj.npz",
    params:
        job_hash=job_hash,
        models=model_args,
    threads: 1
    log:
        f"{LOGS}/evaluate/{{backend}}/{{study}}/{{run}}/n{{n}}_seed{{seed}}.log",
    shell:
        "{PY} -m madpinn evaluate --config {RESOLVED} --study {wildcards.study} --run {wildcards.run}"
        " --n-agents {wildcards.n} --seed {wildcards.seed} --backend {wildcards.backend}"
        " --out {output.parquet} {params.models} --threads {threads} 2>&1 | tee {log}"
