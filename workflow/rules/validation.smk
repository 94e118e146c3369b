# Independent validation of the value functions (issue 15): V_s against a grid HJ solution
# (hj_reachability), V̂ by scenario-based verification in the exact 3-agent dynamics.


rule solve_vs_grid:
    input:
        tracking=TRACKING,
    output:
        solution=f"{RESULTS}/validation/vs_grid_solution.npz",
    params:
        config=RESOLVED,
        settings=settings_hash("solve-vs-grid"),
        source=source_hash("solve-vs-grid"),
    threads: 2
    resources:
        mem_mb=4000,
        runtime=60,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/solve_vs_grid.log",
    shell:
        "python -m madpinn solve-vs-grid --config {params.config:q} --out {output.solution:q} --no-progress 2>&1 | tee {log:q}"


rule validate_vs_grid:
    input:
        tracking=TRACKING,
        # str(): a rules.X reference pins the producer to X; the shipped overlay's install rule must
        # be able to provide the model instead
        model=str(rules.train_vs.output.model),
        grid=rules.solve_vs_grid.output.solution,
    output:
        report=f"{RESULTS}/validation/vs_grid.json",
        png=report(kept(f"{FIGURES}/fig_vs_grid.png"), caption="../report/fig_vs_grid.rst",
                   category=REPORT_SECTIONS["value_functions"], labels={"Item": "fig_vs_grid: V_s vs the grid solution"}),   # REPORT_LABELS (report.smk)
        pdf=kept(f"{FIGURES}/fig_vs_grid.pdf"),
    params:
        config=RESOLVED,
        stem=stem_of("png"),
        settings=settings_hash("validate-vs-grid"),
        source=source_hash("validate-vs-grid"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/validate_vs_grid.log",
    shell:
        "python -m madpinn validate-vs-grid --config {params.config:q} --model vs={input.model:q} --grid {input.grid:q}"
        " --out {output.report:q} --fig-stem {params.stem:q} --threads {threads} 2>&1 | tee {log:q}"


register_targets(f"{RESULTS}/validation/vs_grid.json", *[f"{FIGURES}/fig_vs_grid.{ext}" for ext in ("pdf", "png")])


# Scenario verification of the base V̂ and of each V̂ variant a configured run loads (fig_vhat_budget:
# ε per budget): one rule over the model names vhat / vhat_<variant>.
VERIFIED_VHATS = [vf_model_name("vhat", v) for v in [None, *VHAT_VARIANTS]]


rule verify_vhat:
    input:
        tracking=TRACKING,
        model=f"{RESULTS}/models/{{vhat}}.pt",   # rules.train_vhat / train_vhat_variant (or the shipped model)
    output:
        report=f"{RESULTS}/validation/{{vhat}}_scenario.json",
    wildcard_constraints:
        vhat="|".join(VERIFIED_VHATS),
    params:
        config=RESOLVED,
        settings=settings_hash("verify-vhat"),
        source=source_hash("verify-vhat"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=60,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/verify_{{vhat}}.log",
    shell:
        "python -m madpinn verify-vhat --config {params.config:q} --model vhat={input.model:q} --out {output.report:q}"
        " --threads {threads} 2>&1 | tee {log:q}"


register_targets(f"{RESULTS}/validation/vhat_scenario.json")


# Issue 62 (not in the paper): the calibrated safety level δ of a V̂ per (ε, β), pooled and per
# closing-speed bin, with held-out coverage (calibrate-vhat): a JSON report, which the cells of runs
# that deploy a level (`conformal`) load (madpinn_models, common.smk), and its table, an item of the
# report. Built for the V̂ of every configured run with a level (the protocol's madpinn-cpeps01 rows,
# the overlay workflow/configs/conformal.yaml), or on request: `snakemake -j2 results/validation/vhat_calibration.json`.
rule calibrate_vhat:
    input:
        tracking=TRACKING,
        model=f"{RESULTS}/models/{{vhat}}.pt",   # rules.train_vhat / train_vhat_variant (or the shipped model)
    output:
        report=f"{RESULTS}/validation/{{vhat}}_calibration.json",
        csv=kept(f"{FIGURES}/table_{{vhat}}_calibration.csv"),
        md=kept(f"{FIGURES}/table_{{vhat}}_calibration.md"),
        html=report(kept(f"{FIGURES}/table_{{vhat}}_calibration.html"), caption="../report/table_vhat_calibration.rst",
                    category=REPORT_SECTIONS["our_tables"],
                    labels={"Item": "table_vhat_calibration: V̂'s safety level δ", "Study": "V̂ calibration"}),
    wildcard_constraints:
        vhat="|".join(VERIFIED_VHATS),
    params:
        config=RESOLVED,
        settings=settings_hash("calibrate-vhat"),
        source=source_hash("calibrate-vhat"),
    cache: True   # profiles/shipped restores it from output_cache/ (≈ 4 min on one core; the level cells wait for it)
    threads: 1
    resources:
        mem_mb=2000,
        runtime=60,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/calibrate_{{vhat}}.log",
    shell:
        "python -m madpinn calibrate-vhat --config {params.config:q} --model vhat={input.model:q} --out {output.report:q}"
        " --table-csv {output.csv:q} --table-md {output.md:q} --table-html {output.html:q} --threads {threads} 2>&1 | tee {log:q}"


for _vhat in conformal_vhats():
    register_targets(calibration_report(_vhat), *[f"{FIGURES}/table_{_vhat}_calibration.{ext}" for ext in ("csv", "md")])

CONFORMAL_STUDIES = conformal_studies(config)
"""validation-seed studies with a run that deploys a calibrated level (overlay workflow/configs/conformal.yaml;
a protocol study's level row, main's madpinn-cpeps01, is a table row, not this page's)"""
if CONFORMAL_STUDIES:

    rule conformal_cells:   # `snakemake -j2 conformal_cells`: every cell of those studies (closed loop, heavy)
        input:
            lambda w: studies_results(CONFORMAL_STUDIES),

    # The calibrated level in closed loop (issue 62, not in the paper): per study, run and N the cells
    # beside V̂ alone and the hand-tuned rows, the sentence the issue asks for (does a level reach the
    # paper's safety where V̂ alone does not, at what cost) and the closed-loop collided share per
    # closing-speed bin beside the calibration's ε, δ and held-out rate. Not part of all:
    #   snakemake -j2 conformal_page --configfile workflow/configs/shipped.yaml workflow/configs/conformal.yaml
    rule conformal_page:
        input:
            tracking=TRACKING,
            results=lambda w: studies_results(CONFORMAL_STUDIES),
            calibration=conformal_page_calibration,
        output:
            csv=kept(f"{FIGURES}/conformal/conformal.csv"),
            gap=kept(f"{FIGURES}/conformal/speed_gap.csv"),
            json=kept(f"{FIGURES}/conformal/conformal.json"),
            md=kept(f"{FIGURES}/conformal/conformal.md"),
            html=report(kept(f"{FIGURES}/conformal/conformal.html"), caption="../report/conformal.rst",
                        category=REPORT_SECTIONS["our_tables"],
                        labels={"Item": "conformal: V̂ with a calibrated level in closed loop", "Study": "conformal_*"}),
            png=report(kept(f"{FIGURES}/conformal/fig_conformal.png"), caption="../report/conformal.rst",
                       category=REPORT_SECTIONS["our_tables"],
                       labels={"Item": "fig_conformal", "Study": "conformal_*"}),
            pdf=kept(f"{FIGURES}/conformal/fig_conformal.pdf"),
        params:
            config=RESOLVED,
            settings=settings_hash("conformal-page"),
            source=source_hash("conformal-page"),
            out_dir=out_dir_of("csv"),
        resources:
            mem_mb=2000,
            runtime=10,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/conformal_page.log",
        shell:
            "python -m madpinn conformal-page --config {params.config:q} --inputs {input.results:q}"
            " --calibration {input.calibration:q} --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"
