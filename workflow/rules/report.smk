# Reproduction report (issue 16): every paper table beside the paper's values, with provenance.
# Included after every method's rule file (TABLES and METHOD_MODELS complete) and before tables.smk.
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
        md=REPORT_OUTPUTS[0],
        json=REPORT_OUTPUTS[1],
    params:
        config=RESOLVED,
        tables=[f"{n}={s}" for n, s in _REPORT_TABLES.items()],
        settings=settings_hash("reproduction", studies=sorted(set(_REPORT_TABLES.values()))),
        source=source_hash("reproduction"),
        out_dir=out_dir_of("md"),
    resources:
        mem_mb=2000,
        runtime=15,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/reproduction_report.log",
    shell:
        "python -m madpinn reproduction --config {params.config:q} --tables {params.tables:q} --inputs {input.results:q}"
        " --oracle {input.oracle:q} --models {input.models:q} --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"


EXTRA_TARGETS += REPORT_OUTPUTS
