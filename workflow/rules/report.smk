# Reproduction report (issue 16): every paper table beside the paper's values, with provenance.
# Included after every method's rule file (TABLES and METHOD_INPUTS complete) and before tables.smk.
def study_models(study):
    """Model files the runs of a study load (for checksums in the report)."""
    return sorted({m for run in config["studies"][study]["runs"]
                   for m in METHOD_INPUTS.get(run, METHOD_INPUTS.get(run.split("-")[0], []))})


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
