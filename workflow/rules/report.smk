# Oracle cost lower bounds (SPEC §3) and the reproduction report (issue 16).
# Included after every method's rule file (TABLES, METHOD_INPUTS complete) and before tables.smk.
ORACLE_DIR = f"{RESULTS}/oracle"

wildcard_constraints:
    arena=r"[a-z_]+",


def oracle_scenarios(arena, n, seed):
    """Scenarios 0..S-1 of (arena, N, seed) that any study evaluates (S: the largest count)."""
    counts = [st["scenarios"] for st in config["studies"].values()
              if st["arena"] == arena and int(n) in st["agent_counts"] and int(seed) in st["seeds"]]
    if not counts:
        raise ValueError(f"no study evaluates arena {arena}, N={n}, seed {seed}")
    return max(counts)


def oracle_inputs(study):
    st = config["studies"][study]
    return [f"{ORACLE_DIR}/{st['arena']}/n{n}_seed{seed}.parquet" for n in st["agent_counts"] for seed in st["seeds"]]


def study_models(study):
    """Model files the runs of a study load (for checksums in the report)."""
    return sorted({m for run in config["studies"][study]["runs"]
                   for m in METHOD_INPUTS.get(run, METHOD_INPUTS.get(run.split("-")[0], []))})


# One job per (arena, N, seed): the per-scenario lone-agent lower bound (cached across studies).
rule oracle:
    output:
        f"{ORACLE_DIR}/{{arena}}/n{{n}}_seed{{seed}}.parquet",
    params:
        scenarios=lambda w: oracle_scenarios(w.arena, w.n, w.seed),
        dt=config["oracle"]["dt"],
        arena=lambda w: config["arenas"][w.arena],
    threads: 1
    log:
        f"{LOGS}/oracle/{{arena}}/n{{n}}_seed{{seed}}.log",
    shell:
        "{PY} -m madpinn oracle --config {RESOLVED} --arena {wildcards.arena} --n-agents {wildcards.n}"
        " --seed {wildcards.seed} --scenarios {params.scenarios} --out {output} 2>&1 | tee {log}"


_REPORT_TABLES = {name: study for name, (study, _) in TABLES.items() if study in config["studies"]}
REPORT_OUTPUTS = [f"{FIGURES}/reproduction.md", f"{FIGURES}/reproduction.json"]


# `snakemake -j2 reproduction_report`: every table with our mean ± std beside the paper's values.
rule reproduction_report:
    input:
        tracking=TRACKING,
        results=sorted({p for s in _REPORT_TABLES.values() for p in study_results(s)}),
        oracle=sorted({p for s in _REPORT_TABLES.values() for p in oracle_inputs(s)}),
        models=sorted({m for s in _REPORT_TABLES.values() for m in study_models(s)}),
    output:
        REPORT_OUTPUTS,
    params:
        tables=" ".join(f"{n}={s}" for n, s in _REPORT_TABLES.items()),
    log:
        f"{LOGS}/reproduction_report.log",
    shell:
        "{PY} -m madpinn reproduction --config {RESOLVED} --tables {params.tables} --inputs {input.results}"
        " --oracle {input.oracle} --models {input.models} --out-dir {FIGURES} 2>&1 | tee {log}"


EXTRA_TARGETS += REPORT_OUTPUTS
