# Paper figures, each its own target (e.g. `snakemake -j2 fig_cost_safety`).
FIG_EXTS = ["pdf", "png"]
TRAJ = config["figures"]["trajectories"]


def traj_inputs(wildcards=None):
    st = config["studies"][TRAJ["study"]]
    return [eval_path(TRAJ["study"], run, TRAJ["n_agents"], TRAJ["seed"]).replace(".parquet", "_traj.npz") for run in st["runs"]]


def run_labels(study):
    """Labels the tables and figures print for a study's runs (part of their params hash)."""
    return {run: method_config(config, run)[1].get("label", run) for run in config["studies"][study]["runs"]}


if "main" in config["studies"]:

    rule fig_cost_safety:
        input:
            tracking=TRACKING,
            results=study_results("main"),
        output:
            png=report(f"{FIGURES}/fig_cost_safety.png", caption="../report/fig_cost_safety.rst", category="Figures"),
            pdf=f"{FIGURES}/fig_cost_safety.pdf",
        params:
            settings=settings_hash("experiment", extra=run_labels("main")),
            source=source_hash("tables"),
        resources:
            mem_mb=2000,
            runtime=15,
        log:
            f"{LOGS}/fig_cost_safety.log",
        shell:
            "{PY:q} -m madpinn figure --config {RESOLVED:q} --name fig_cost_safety --inputs {input.results:q}"
            " --out-dir {FIGURES:q} 2>&1 | tee {log:q}"

    EXTRA_TARGETS += expand(f"{FIGURES}/fig_cost_safety.{{ext}}", ext=FIG_EXTS)


rule fig_trajectories:
    input:
        tracking=TRACKING,
        traj=traj_inputs(),
    output:
        png=report(f"{FIGURES}/fig_trajectories.png", caption="../report/fig_trajectories.rst", category="Figures"),
        pdf=f"{FIGURES}/fig_trajectories.pdf",
    params:
        settings=settings_hash("experiment", "figures.trajectories", extra=run_labels(TRAJ["study"])),
        source=source_hash("tables"),
    resources:
        mem_mb=2000,
        runtime=15,
    log:
        f"{LOGS}/fig_trajectories.log",
    shell:
        "{PY:q} -m madpinn figure --config {RESOLVED:q} --name fig_trajectories --inputs {input.traj:q}"
        " --out-dir {FIGURES:q} 2>&1 | tee {log:q}"


EXTRA_TARGETS += expand(f"{FIGURES}/fig_trajectories.{{ext}}", ext=FIG_EXTS)
