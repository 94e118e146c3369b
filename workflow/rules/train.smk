# Value functions (issue 3): train V̂ and V_s, validate them, and draw their figures.
# Other rule files read the models as `rules.train_vhat.output.model` / `rules.train_vs.output.model`.
# Helpers (init_model, init_arg, train_runtime): common.smk.
VF_THREADS = int(config["value_functions"]["threads"])


rule train_vhat:
    input:
        tracking=TRACKING,
        init=init_model("vhat"),
    output:
        model=f"{RESULTS}/models/vhat.pt",
        loss=f"{RESULTS}/models/vhat_loss.csv",
        summary=f"{RESULTS}/models/vhat_train.json",
    params:
        config=RESOLVED,
        init=init_arg("vhat"),
        settings=settings_hash("train-value", kind="vhat"),
        source=source_hash("train-value"),
    threads: VF_THREADS
    resources:
        mem_mb=4000,
        runtime=train_runtime("vhat"),
        **TRAIN_GPU,
    priority: 100
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/train_vhat.log",
    shell:
        "python -m madpinn train-value --config {params.config:q} --kind vhat --out {output.model:q} {params.init:q}"
        " --threads {threads}"
        " 2>&1 | tee {log:q}"


rule train_vs:
    input:
        tracking=TRACKING,
        init=init_model("vs"),
    output:
        model=f"{RESULTS}/models/vs.pt",
        loss=f"{RESULTS}/models/vs_loss.csv",
        summary=f"{RESULTS}/models/vs_train.json",
    params:
        config=RESOLVED,
        init=init_arg("vs"),
        settings=settings_hash("train-value", kind="vs"),
        source=source_hash("train-value"),
    threads: VF_THREADS
    resources:
        mem_mb=4000,
        runtime=train_runtime("vs"),
        **TRAIN_GPU,
    priority: 50
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/train_vs.log",
    shell:
        "python -m madpinn train-value --config {params.config:q} --kind vs --out {output.model:q} {params.init:q}"
        " --threads {threads}"
        " 2>&1 | tee {log:q}"


# V̂ variants (issue 33; value_functions.vhat_variants, each merged over value_functions.vhat): one
# training per variant a configured MAD-PINN run loads (`vhat: <name>`), by the same command with
# --variant, which merges the variant before anything reads the settings (its training hash too).
VHAT_VARIANTS = vhat_variants_used()
if VHAT_VARIANTS:

    rule train_vhat_variant:
        input:
            tracking=TRACKING,
            init=lambda wildcards: init_model("vhat", wildcards.variant),
        output:
            model=f"{RESULTS}/models/vhat_{{variant}}.pt",
            loss=f"{RESULTS}/models/vhat_{{variant}}_loss.csv",
            summary=f"{RESULTS}/models/vhat_{{variant}}_train.json",
        wildcard_constraints:
            variant="|".join(VHAT_VARIANTS),
        params:
            config=RESOLVED,
            init=lambda wildcards: init_arg("vhat", wildcards.variant),
            settings=settings_hash("train-value", "variant", kind="vhat"),
            source=source_hash("train-value"),
        threads: VF_THREADS
        resources:
            mem_mb=4000,
            runtime=lambda wildcards: train_runtime("vhat", wildcards.variant),
            **TRAIN_GPU,
        priority: 100
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/train_vhat_{{variant}}.log",
        shell:
            "python -m madpinn train-value --config {params.config:q} --kind vhat --variant {wildcards.variant:q}"
            " --out {output.model:q} {params.init:q} --threads {threads}"
            " 2>&1 | tee {log:q}"


# V_s variants (issue 63; value_functions.vs_variants, each merged over value_functions.vs, e.g. one
# trained for a study's 3-D agent model: its `agents`): one training per variant a configured
# MAD-PINN run loads (`vs: <name>`), by the same command with --variant.
VS_VARIANTS = vf_variants_used("vs")
if VS_VARIANTS:

    rule train_vs_variant:
        input:
            tracking=TRACKING,
            init=lambda wildcards: init_model("vs", wildcards.variant),
        output:
            model=f"{RESULTS}/models/vs_{{variant}}.pt",
            loss=f"{RESULTS}/models/vs_{{variant}}_loss.csv",
            summary=f"{RESULTS}/models/vs_{{variant}}_train.json",
        wildcard_constraints:
            variant="|".join(VS_VARIANTS),
        params:
            config=RESOLVED,
            init=lambda wildcards: init_arg("vs", wildcards.variant),
            settings=settings_hash("train-value", "variant", kind="vs"),
            source=source_hash("train-value"),
        threads: VF_THREADS
        resources:
            mem_mb=4000,
            runtime=lambda wildcards: train_runtime("vs", wildcards.variant),
            **TRAIN_GPU,
        priority: 50
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/train_vs_{{variant}}.log",
        shell:
            "python -m madpinn train-value --config {params.config:q} --kind vs --variant {wildcards.variant:q}"
            " --out {output.model:q} {params.init:q} --threads {threads}"
            " 2>&1 | tee {log:q}"


rule validate_vs:
    input:
        tracking=TRACKING,
        model=str(rules.train_vs.output.model),  # str(): see run_models (shipped overlay)
    output:
        report=f"{RESULTS}/validation/vs_rollouts.json",
        png=report(kept(f"{FIGURES}/fig_vs_slices.png"), caption="../report/fig_vs_slices.rst",
                   category=REPORT_SECTIONS["value_functions"], labels={"Item": "fig_vs_slices: V_s slices"}),   # REPORT_LABELS (report.smk)
        pdf=kept(f"{FIGURES}/fig_vs_slices.pdf"),
    params:
        config=RESOLVED,
        stem=stem_of("png"),
        settings=settings_hash("validate-vs"),
        source=source_hash("validate-vs"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/validate_vs.log",
    shell:
        "python -m madpinn validate-vs --config {params.config:q} --model vs={input.model:q} --out {output.report:q}"
        " --fig-stem {params.stem:q} --threads {threads} 2>&1 | tee {log:q}"


rule validate_vhat:
    input:
        tracking=TRACKING,
        model=str(rules.train_vhat.output.model),  # str(): see run_models (shipped overlay)
    output:
        report=f"{RESULTS}/validation/vhat_residuals.json",
    params:
        config=RESOLVED,
        settings=settings_hash("validate-vhat"),
        source=source_hash("validate-vhat"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/validate_vhat.log",
    shell:
        "python -m madpinn validate-vhat --config {params.config:q} --model vhat={input.model:q} --out {output.report:q}"
        " --threads {threads} 2>&1 | tee {log:q}"


rule fig_value_heatmap:
    input:
        tracking=TRACKING,
        model=str(rules.train_vhat.output.model),  # str(): see run_models (shipped overlay)
    output:
        png=report(kept(f"{FIGURES}/fig_value_heatmap.png"), caption="../report/fig_value_heatmap.rst",
                   category=REPORT_SECTIONS["paper_figures"], labels={"Item": "Fig. 4", "Shows": "value heatmap"}),
        pdf=kept(f"{FIGURES}/fig_value_heatmap.pdf"),
        json=kept(f"{FIGURES}/fig_value_heatmap.json"),   # the figure's reading in numbers (claims page)
    params:
        config=RESOLVED,
        stem=stem_of("png"),
        settings=settings_hash("fig-value-heatmap"),
        source=source_hash("fig-value-heatmap"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=15,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/fig_value_heatmap.log",
    shell:
        "python -m madpinn fig-value-heatmap --config {params.config:q} --model vhat={input.model:q} --out-stem {params.stem:q}"
        " --threads {threads} 2>&1 | tee {log:q}"


register_targets(
    f"{RESULTS}/validation/vs_rollouts.json",
    f"{RESULTS}/validation/vhat_residuals.json",
    *[f"{FIGURES}/{name}.{ext}" for name in ("fig_value_heatmap", "fig_vs_slices") for ext in ("pdf", "png")],
    f"{FIGURES}/fig_value_heatmap.json",
)
