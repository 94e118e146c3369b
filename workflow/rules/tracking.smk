# The MLflow store and this configuration's experiment are created once, before the fan-out:
# parallel first writers race while creating a SQLite schema.
rule tracking_init:
    output:
        TRACKING,
    params:
        config=RESOLVED,
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/tracking_init.log",
    shell:
        "python -m madpinn tracking-init --config {params.config:q} --out {output:q} 2>&1 | tee {log:q}"
