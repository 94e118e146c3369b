# Value functions (issue 3): train V̂ and V_s, validate them, and draw their figures.
# Other rule files depend on VHAT_MODEL / VS_MODEL (e.g. METHOD_INPUTS["madpinn"] = [VHAT_MODEL, VS_MODEL]).
import os

VHAT_MODEL = f"{RESULTS}/models/vhat.pt"
VS_MODEL = f"{RESULTS}/models/vs.pt"
VF_THREADS = int(config["value_functions"]["threads"])


def init_model(kind):
    """The model a ``value_functions.<kind>.init_from`` fine-tuning run starts from (or nothing)."""
    path = config["value_functions"][kind].get("init_from")
    if not path:
        return []
    return [path if os.path.isabs(path) else f"{RESULTS}/{path}"]


def train_settings(kind):
    """Everything the trained weights and their summary depend on (the job's params hash)."""
    return settings_hash(f"value_functions.{kind}", "value_functions.seed", "agents", "observation", "dtype")


def train_runtime(kind):
    """Slurm time limit (min): ~1.7 min per 1000 iterations of 4 096 samples on one core, ×2 margin."""
    v = config["value_functions"][kind]
    its = int(v["iterations"]) + int((v.get("fine_tune") or {}).get("iterations", 0))
    return 10 + int(3.5 * its * int(v["batch_size"]) / 4.096e6)


rule train_vhat:
    input:
        tracking=TRACKING,
        init=init_model("vhat"),
    output:
        model=VHAT_MODEL,
        loss=f"{RESULTS}/models/vhat_loss.csv",
        summary=f"{RESULTS}/models/vhat_train.json",
    params:
        settings=train_settings("vhat"),
        source=source_hash("value"),
    threads: VF_THREADS
    resources:
        mem_mb=4000,
        runtime=train_runtime("vhat"),
        **TRAIN_GPU,
    priority: 100
    log:
        f"{LOGS}/train_vhat.log",
    shell:
        "{PY:q} -m madpinn train-value --config {RESOLVED:q} --kind vhat --out {output.model:q} --threads {threads}"
        " 2>&1 | tee {log:q}"


rule train_vs:
    input:
        tracking=TRACKING,
        init=init_model("vs"),
    output:
        model=VS_MODEL,
        loss=f"{RESULTS}/models/vs_loss.csv",
        summary=f"{RESULTS}/models/vs_train.json",
    params:
        settings=train_settings("vs"),
        source=source_hash("value"),
    threads: VF_THREADS
    resources:
        mem_mb=4000,
        runtime=train_runtime("vs"),
        **TRAIN_GPU,
    priority: 50
    log:
        f"{LOGS}/train_vs.log",
    shell:
        "{PY:q} -m madpinn train-value --config {RESOLVED:q} --kind vs --out {output.model:q} --threads {threads}"
        " 2>&1 | tee {log:q}"


rule validate_vs:
    input:
        tracking=TRACKING,
        model=VS_MODEL,
    output:
        report=f"{RESULTS}/validation/vs_rollouts.json",
        png=report(f"{FIGURES}/fig_vs_slices.png", caption="../report/fig_vs_slices.rst", category="Value functions"),
        pdf=f"{FIGURES}/fig_vs_slices.pdf",
    params:
        stem=f"{FIGURES}/fig_vs_slices",
        settings=settings_hash("value_functions.vs.validation", "value_functions.seed", "dtype"),
        source=source_hash("value"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    log:
        f"{LOGS}/validate_vs.log",
    shell:
        "{PY:q} -m madpinn validate-vs --config {RESOLVED:q} --model {input.model:q} --out {output.report:q}"
        " --fig-stem {params.stem:q} --threads {threads} 2>&1 | tee {log:q}"


rule validate_vhat:
    input:
        tracking=TRACKING,
        model=VHAT_MODEL,
    output:
        report=f"{RESULTS}/validation/vhat_residuals.json",
    params:
        settings=settings_hash("value_functions.vhat.validation", "value_functions.seed", "dtype"),
        source=source_hash("value"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    log:
        f"{LOGS}/validate_vhat.log",
    shell:
        "{PY:q} -m madpinn validate-vhat --config {RESOLVED:q} --model {input.model:q} --out {output.report:q}"
        " --threads {threads} 2>&1 | tee {log:q}"


rule fig_value_heatmap:
    input:
        tracking=TRACKING,
        model=VHAT_MODEL,
    output:
        png=report(f"{FIGURES}/fig_value_heatmap.png", caption="../report/fig_value_heatmap.rst",
                   category="Value functions"),
        pdf=f"{FIGURES}/fig_value_heatmap.pdf",
    params:
        stem=f"{FIGURES}/fig_value_heatmap",
        settings=settings_hash("arenas.small", "dtype"),
        source=source_hash("value"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=15,
    log:
        f"{LOGS}/fig_value_heatmap.log",
    shell:
        "{PY:q} -m madpinn fig-value-heatmap --config {RESOLVED:q} --model {input.model:q} --out-stem {params.stem:q}"
        " --threads {threads} 2>&1 | tee {log:q}"


EXTRA_TARGETS += [
    f"{RESULTS}/validation/vs_rollouts.json",
    f"{RESULTS}/validation/vhat_residuals.json",
    *[f"{FIGURES}/{name}.{ext}" for name in ("fig_value_heatmap", "fig_vs_slices") for ext in ("pdf", "png")],
]
