# Oracle cost lower bound of each scenario (SPEC §3; madpinn/evaluation/oracle.py): one job per
# (arena, N, seed), cached and shared by every study, table and figure on those scenarios.
# ORACLE_DIR, oracle_scenarios, oracle_inputs: common.smk

wildcard_constraints:
    arena=r"[a-z_]+",


# One job per (arena, N, seed): the per-scenario lone-agent lower bound (cached across studies).
rule oracle:
    output:
        f"{ORACLE_DIR}/{{arena}}/n{{n}}_seed{{seed}}.parquet",
    params:
        config=RESOLVED,
        scenarios=lambda w: oracle_scenarios(w.arena, w.n, w.seed),
        settings=settings_hash("oracle", "agents", "arenas"),
        source=source_hash("oracle"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=240,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/oracle/{{arena}}/n{{n}}_seed{{seed}}.log",
    shell:
        "python -m madpinn oracle --config {params.config:q} --arena {wildcards.arena:q} --n-agents {wildcards.n}"
        " --seed {wildcards.seed} --scenarios {params.scenarios} --out {output:q} 2>&1 | tee {log:q}"
