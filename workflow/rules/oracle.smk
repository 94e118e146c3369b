# Oracle cost lower bound of each scenario (SPEC §3; madpinn/evaluation/oracle.py): one job per
# (arena, N, seed, scenario count), shared by every study, table and figure on those scenarios;
# `oracle_pattern` does the same for a structured-conflict pattern's scenarios (madpinn/conflicts.py).
# ORACLE_DIR, oracle_inputs: common.smk

wildcard_constraints:
    arena=r"[a-z_]+",
    pattern=r"[a-z0-9_]+",
    scenarios=r"\d+",


# One job per (arena, N, seed, scenario count): the per-scenario lone-agent lower bound.
rule oracle:
    input:
        tracking=TRACKING,
    output:
        bounds=f"{ORACLE_DIR}/{{arena}}/n{{n}}_seed{{seed}}_s{{scenarios}}.parquet",
    params:
        config=RESOLVED,
        settings=settings_hash("oracle", "arena"),
        source=source_hash("oracle"),
        cell=cell_key,
    cache: True
    threads: 1
    resources:
        mem_mb=2000,
        runtime=240,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/oracle/{{arena}}/n{{n}}_seed{{seed}}_s{{scenarios}}.log",
    shell:
        "python -m madpinn oracle --config {params.config:q} --arena {wildcards.arena:q} --n-agents {wildcards.n}"
        " --seed {wildcards.seed} --scenarios {wildcards.scenarios} --out {output.bounds:q} 2>&1 | tee {log:q}"


# The same for the scenarios of a structured-conflict pattern (studies conflict_*); a rule of its
# own (`use rule … with:` cannot change `shell:`), so the uniform rule's jobs keep their code.
rule oracle_pattern:
    input:
        tracking=TRACKING,
    output:
        bounds=f"{ORACLE_DIR}/{{arena}}/{{pattern}}/n{{n}}_seed{{seed}}_s{{scenarios}}.parquet",
    params:
        config=RESOLVED,
        settings=settings_hash("oracle", "arena"),
        source=source_hash("oracle"),
        cell=cell_key,
    cache: True
    threads: 1
    resources:
        mem_mb=2000,
        runtime=240,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/oracle/{{arena}}/{{pattern}}/n{{n}}_seed{{seed}}_s{{scenarios}}.log",
    shell:
        "python -m madpinn oracle --config {params.config:q} --arena {wildcards.arena:q} --n-agents {wildcards.n}"
        " --seed {wildcards.seed} --scenarios {wildcards.scenarios} --pattern {wildcards.pattern:q}"
        " --out {output.bounds:q} 2>&1 | tee {log:q}"
