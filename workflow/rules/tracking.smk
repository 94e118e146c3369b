# The MLflow store and this configuration's experiment are created once, before the fan-out:
# parallel first writers race while creating a SQLite schema.
rule tracking_init:
    output:
        TRACKING,
    log:
        f"{LOGS}/tracking_init.log",
    shell:
        "{PY} -m madpinn tracking-init --config {RESOLVED} --out {output} 2>&1 | tee {log}"
