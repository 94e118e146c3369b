# Paper figures, each its own target (e.g. `snakemake -j2 fig_cost_safety`).
FIG_EXTS = ["pdf", "png"]
TRAJ = config["figures"]["trajectories"]


def traj_inputs(wildcards=None):
    st = config["studies"][TRAJ["study"]]
    return [eval_path(TRAJ["study"], run, TRAJ["n_agents"], TRAJ["seed"]).replace(".parquet", "_traj.npz") for run in st["runs"]]


if "main" in config["studies"]:

    rule fig_cost_safety:
        input:
            tracking=TRACKING,
            results=study_results("main"),
            oracle=oracle_inputs("main"),
        output:
            expand(f"{FIGURES}/fig_cost_safety.{{ext}}", ext=FIG_EXTS),
        log:
            f"{LOGS}/fig_cost_safety.log",
        shell:
            "{PY} -m madpinn figure --config {RESOLVED} --name fig_cost_safety --inputs {input.results} --oracle {input.oracle}"
            " --out-dir {FIGURES} 2>&1 | tee {log}"

    EXTRA_TARGETS += expand(f"{FIGURES}/fig_cost_safety.{{ext}}", ext=FIG_EXTS)


rule fig_trajectories:
    input:
        tracking=TRACKING,
        traj=traj_inputs(),
    output:
        expand(f"{FIGURES}/fig_trajectories.{{ext}}", ext=FIG_EXTS),
    log:
        f"{LOGS}/fig_trajectories.log",
    shell:
        "{PY} -m madpinn figure --config {RESOLVED} --name fig_trajectories --inputs {input.traj}"
        " --out-dir {FIGURES} 2>&1 | tee {log}"


EXTRA_TARGETS += expand(f"{FIGURES}/fig_trajectories.{{ext}}", ext=FIG_EXTS)
