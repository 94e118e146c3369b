# Paper figures, each its own target (e.g. `snakemake -j2 fig_cost_safety`).
FIG_EXTS = ["pdf", "png"]
TRAJ = config["figures"]["trajectories"]


if "main" in config["studies"]:

    rule fig_cost_safety:
        input:
            tracking=TRACKING,
            results=study_results("main"),
            oracle=oracle_inputs("main"),
        output:
            png=report(kept(f"{FIGURES}/fig_cost_safety.png"), caption="../report/fig_cost_safety.rst",
                       category=REPORT_SECTIONS["paper_figures"], labels={"Item": "Fig. 2", "Shows": "cost vs safety"}),
            pdf=kept(f"{FIGURES}/fig_cost_safety.pdf"),
        params:
            config=RESOLVED,
            settings=settings_hash("figure", name="fig_cost_safety", study="main"),
            source=source_hash("figure"),
            out_dir=out_dir_of("png"),
        resources:
            mem_mb=2000,
            runtime=15,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/fig_cost_safety.log",
        shell:
            "python -m madpinn figure --config {params.config:q} --name fig_cost_safety --inputs {input.results:q}"
            " --oracle {input.oracle:q} --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"

    register_targets(*expand(f"{FIGURES}/fig_cost_safety.{{ext}}", ext=FIG_EXTS))


rule fig_trajectories:
    input:
        tracking=TRACKING,
        traj=traj_inputs(),
    output:
        png=report(kept(f"{FIGURES}/fig_trajectories.png"), caption="../report/fig_trajectories.rst",
                   category=REPORT_SECTIONS["paper_figures"], labels={"Item": "Fig. 3", "Shows": "trajectories"}),
        pdf=kept(f"{FIGURES}/fig_trajectories.pdf"),
    params:
        config=RESOLVED,
        settings=settings_hash("figure", name="fig_trajectories", study=TRAJ["study"]),
        source=source_hash("figure"),
        out_dir=out_dir_of("png"),
    resources:
        mem_mb=2000,
        runtime=15,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/fig_trajectories.log",
    shell:
        "python -m madpinn figure --config {params.config:q} --name fig_trajectories --inputs {input.traj:q}"
        " --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"


register_targets(*expand(f"{FIGURES}/fig_trajectories.{{ext}}", ext=FIG_EXTS))


# The large arena's safety–cost frontier (issue 33 item 4, not in the paper): every V̂ and speed
# governor of study large_arena_frontier at Table II's agent counts, the paper's points overlaid.
if "large_arena_frontier" in config["studies"]:

    rule fig_large_arena_frontier:
        input:
            tracking=TRACKING,
            results=study_results("large_arena_frontier"),
        output:
            png=report(kept(f"{FIGURES}/fig_large_arena_frontier.png"), caption="../report/fig_large_arena_frontier.rst",
                       category=REPORT_SECTIONS["our_tables"],
                       labels={"Item": "fig_large_arena_frontier", "Shows": "large-arena safety vs cost"}),
            pdf=kept(f"{FIGURES}/fig_large_arena_frontier.pdf"),
        params:
            config=RESOLVED,
            settings=settings_hash("figure", name="fig_large_arena_frontier", study="large_arena_frontier"),
            source=source_hash("figure"),
            out_dir=out_dir_of("png"),
        resources:
            mem_mb=2000,
            runtime=15,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/fig_large_arena_frontier.log",
        shell:
            "python -m madpinn figure --config {params.config:q} --name fig_large_arena_frontier"
            " --study large_arena_frontier --inputs {input.results:q} --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"

    if "large_arena_frontier" in studies_in_all():   # in_all: false: built by its own target only
        register_targets(*expand(f"{FIGURES}/fig_large_arena_frontier.{{ext}}", ext=FIG_EXTS))


# Issue 46: safety against V̂'s training samples (each budget a V̂ variant), a panel per budget study
# (BUDGET_STUDIES, common.smk), the paper's values as lines, each V̂'s verification in the CSV.
if "vhat_budget" in config["studies"]:

    rule fig_vhat_budget:
        input:
            tracking=TRACKING,
            results=[f for st in BUDGET_STUDIES for f in study_results(st)],
            models=lambda wildcards: [a.split("=", 1)[1] for a in budget_vhat_args(wildcards)],
            verify=lambda wildcards: [a.split("=", 1)[1] for a in budget_verify_args(wildcards)],
        output:
            png=report(kept(f"{FIGURES}/fig_vhat_budget.png"), caption="../report/fig_vhat_budget.rst",
                       category=REPORT_SECTIONS["our_tables"],
                       labels={"Item": "fig_vhat_budget", "Shows": "safety vs V̂ training samples"}),
            pdf=kept(f"{FIGURES}/fig_vhat_budget.pdf"),
            csv=kept(f"{FIGURES}/fig_vhat_budget.csv"),
        params:
            config=RESOLVED,
            settings=settings_hash("figure", name="fig_vhat_budget", study=BUDGET_STUDIES),
            source=source_hash("figure"),
            out_dir=out_dir_of("png"),
            vhat=budget_vhat_args,
            verify=budget_verify_args,
            studies=BUDGET_STUDIES,
        resources:
            mem_mb=2000,
            runtime=15,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/fig_vhat_budget.log",
        shell:
            "python -m madpinn figure --config {params.config:q} --name fig_vhat_budget --study {params.studies:q}"
            " --inputs {input.results:q} --vhat {params.vhat:q} --verify {params.verify:q}"
            " --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"

    if "vhat_budget" in studies_in_all():   # in_all: false (config.yaml studies.vhat_budget): built by its own target only
        register_targets(*expand(f"{FIGURES}/fig_vhat_budget.{{ext}}", ext=[*FIG_EXTS, "csv"]))
