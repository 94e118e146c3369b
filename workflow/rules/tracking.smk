# The MLflow store and this configuration's experiment are created once, before the fan-out:
# parallel first writers race while creating a SQLite schema.
rule tracking_init:
    output:
        TRACKING,
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        f"{LOGS}/tracking_init.log",
    shell:
        "{PY:q} -m madpinn tracking-init --config {RESOLVED:q} --out {output:q} 2>&1 | tee {log:q}"
