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
            csv=report(f"{FIGURES}/{_name}.csv", caption=f"../report/{_name}.rst", category="Tables"),
            md=f"{FIGURES}/{_name}.md",
            tex=f"{FIGURES}/{_name}.tex",
        params:
            config=RESOLVED,
            name=_name,
            kind=_kind,
            settings=settings_hash("table", study=_study),
            source=source_hash("table"),
            out_dir=out_dir_of("csv"),
        resources:
            mem_mb=1000,
            runtime=10,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/{_name}.log",
        shell:
            "python -m madpinn table --config {params.config:q} --name {params.name:q} --kind {params.kind:q}"
            " --inputs {input.results:q} --oracle {input.oracle:q} --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"


ALL_TARGETS = all_targets() + EXTRA_TARGETS
