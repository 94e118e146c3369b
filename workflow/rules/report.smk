# Reproduction report (issue 16): every paper table beside the paper's values, with provenance.
# Its inputs are functions of the registered tables and models (report_studies, configured_tables:
# common.smk), so it sees every rule file's registrations wherever it is included.
REPORT_OUTPUTS = [f"{FIGURES}/reproduction.md", f"{FIGURES}/reproduction.json", f"{FIGURES}/reproduction.html"]


# `snakemake -j2 reproduction_report`: every table with our mean ± std beside the paper's values.
# REPORT_LABELS: a report section of two items ("Paper vs ours", "Value-function checks") gives each
# one label. A second label with a different value per item would become a toggle of Snakemake's report
# (a label with two values, each on half the section's items) and the section page would fail to render
# (tests/test_workflow.py::test_report_holds_every_table_and_figure_in_the_papers_order).
rule reproduction_report:
    input:
        tracking=TRACKING,
        results=lambda w: studies_results(report_studies()),
        oracle=lambda w: sorted({p for s in report_studies() for p in oracle_inputs(s)}),
        models=lambda w: sorted({m for s in report_studies() for m in study_models(s)}),
    output:
        md=kept(REPORT_OUTPUTS[0]),   # kept: a failed job never deletes the committed report (common.smk)
        json=kept(REPORT_OUTPUTS[1]),
        html=report(kept(REPORT_OUTPUTS[2]), caption="../report/reproduction.rst", category=REPORT_SECTIONS["reproduction"],
                    labels={"Item": "Reproduction report: every table beside the paper's"}),   # one label: REPORT_LABELS
    params:
        config=RESOLVED,
        tables=lambda w: [f"{n}={s}" for n, s in configured_tables().items()],
        settings=settings_hash("reproduction", studies=report_studies),
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


register_targets(*REPORT_OUTPUTS)


# `snakemake -j2 claims_table`: each claim of the paper tested on the report (issue 47): the cells it
# rests on, our figures with their 95 % intervals, a verdict computed by madpinn/evaluation/claims.py.
CLAIMS_OUTPUTS = [f"{FIGURES}/claims.md", f"{FIGURES}/claims.json", f"{FIGURES}/claims.html"]
NEIGHBOUR_TIMING = f"{FIGURES}/neighbour_timing.json"


# The paper's "neighbour selection takes 1.2 ms per agent" and O(N) (issue 61): the deployment's
# selector timed per agent and update at every protocol agent count, on this machine (< 1 min, one core).
rule neighbour_timing:
    input:
        tracking=TRACKING,
        vs=f"{RESULTS}/models/vs.pt",   # rules.train_vs (or the shipped model); a path, so the rule files may come in any order
    output:
        json=kept(NEIGHBOUR_TIMING),
    params:
        config=RESOLVED,
        settings=settings_hash("neighbour-timing"),
        source=source_hash("neighbour-timing"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/neighbour_timing.log",
    shell:
        "python -m madpinn neighbour-timing --config {params.config:q} --model vs={input.vs:q} --out {output.json:q}"
        " 2>&1 | tee {log:q}"


# The validation-seed pages the claims page reads (each [] or one file): rules.table_ii_readings /
# rules.vhat_recipe (readings.smk) when this run's overlay builds them, else the published page.
CLAIMS_READINGS = claims_page_input("table_ii_verdict", "table_ii_readings", f"{FIGURES}/table_ii_readings/verdict.json")
CLAIMS_RECIPE = claims_page_input("vhat_recipe", "vhat_recipe", f"{FIGURES}/vhat_recipe/vhat_recipe.json")


rule claims_table:
    input:
        tracking=TRACKING,
        report=rules.reproduction_report.output.json,
        timing=NEIGHBOUR_TIMING,
        heatmap=f"{FIGURES}/fig_value_heatmap.json",   # rules.fig_value_heatmap (train.smk); a path, so the rule files may come in any order
        readings=CLAIMS_READINGS,
        recipe=CLAIMS_RECIPE,
    output:
        md=kept(CLAIMS_OUTPUTS[0]),   # kept: a failed job never deletes the committed claims (common.smk)
        json=kept(CLAIMS_OUTPUTS[1]),
        html=report(kept(CLAIMS_OUTPUTS[2]), caption="../report/claims.rst", category=REPORT_SECTIONS["reproduction"],
                    labels={"Item": "Claims of the paper, tested: cells, intervals, verdicts"}),
    params:
        config=RESOLVED,
        settings=settings_hash("claims"),
        source=source_hash("claims"),
        out_dir=out_dir_of("md"),
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/claims_table.log",
    shell:
        "python -m madpinn claims --config {params.config:q} --report {input.report:q} --timing {input.timing:q}"
        " --heatmap {input.heatmap:q} --out-dir {params.out_dir:q}"
        + (" --table-ii-verdict {input.readings:q}" if CLAIMS_READINGS else "")
        + (" --vhat-recipe {input.recipe:q}" if CLAIMS_RECIPE else "")
        + " 2>&1 | tee {log:q}"


register_targets(*CLAIMS_OUTPUTS, NEIGHBOUR_TIMING)
