# One job per (backend, study, run, N, seed) cell: per-scenario Parquet, JSON summary, and the
# first scenario's trajectory; then one MLflow run. Eligible for Snakemake's between-workflow
# output cache (`--cache`, profiles/shipped): a cell whose provenance (code, params, models' bytes
# or training jobs) is already in paths.output_cache is restored from there instead of recomputed.
rule evaluate:
    input:
        unpack(cell_models),
        tracking=TRACKING,
    output:
        parquet=f"{RESULTS}/eval/{{backend}}/{{study}}/{{run}}/n{{n}}_seed{{seed}}.parquet",
        summary=f"{RESULTS}/eval/{{backend}}/{{study}}/{{run}}/n{{n}}_seed{{seed}}.json",
        traj=f"{RESULTS}/eval/{{backend}}/{{study}}/{{run}}/n{{n}}_seed{{seed}}_traj.npz",
    params:
        config=RESOLVED,
        settings=settings_hash("evaluate", "study", "run"),
        source=eval_source_hash,
        models=model_args,
        cell=cell_key,
        device=CELL_DEVICE,
    cache: True
    threads: 1
    priority: eval_priority
    resources:
        mem_mb=eval_mem_mb,
        runtime=eval_runtime,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/evaluate/{{backend}}/{{study}}/{{run}}/n{{n}}_seed{{seed}}.log",
    shell:
        "python -m madpinn evaluate --config {params.config:q} --study {wildcards.study:q} --run {wildcards.run:q}"
        " --n-agents {wildcards.n} --seed {wildcards.seed} --backend {wildcards.backend:q}"
        " --out {output.parquet:q} {params.models:q} --device {params.device:q} --threads {threads} 2>&1 | tee {log:q}"
