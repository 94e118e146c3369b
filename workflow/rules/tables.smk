# Paper tables, each its own target (e.g. `snakemake -j2 table_safety_scaling`).
for _name, (_study, _kind) in TABLES.items():
    if _study not in config["studies"]:
        continue

    rule:
        name:
            _name
        input:
            tracking=TRACKING,
            results=study_results(_study),
            oracle=oracle_inputs(_study),
        output:
            expand(f"{FIGURES}/{_name}.{{ext}}", ext=["csv", "md", "tex"]),
        params:
            name=_name,
            kind=_kind,
        log:
            f"{LOGS}/{_name}.log",
        shell:
            "{PY} -m madpinn table --config {RESOLVED} --name {params.name} --kind {params.kind}"
            " --inputs {input.results} --oracle {input.oracle} --out-dir {FIGURES} 2>&1 | tee {log}"


ALL_TARGETS = all_targets() + EXTRA_TARGETS
