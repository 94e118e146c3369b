# Value functions (issue 3): train V̂ and V_s, validate them, and draw their figures.
# Other rule files read the models as `rules.train_vhat.output.model` / `rules.train_vs.output.model`.
import os

VF_THREADS = int(config["value_functions"]["threads"])


def init_model(kind):
    """The model a ``value_functions.<kind>.init_from`` fine-tuning run starts from (or nothing)."""
    path = config["value_functions"][kind].get("init_from")
    if not path:
        return []
    return [path if os.path.isabs(path) else f"{RESULTS}/{path}"]


def init_arg(kind):
    """``--model init=PATH`` when the run fine-tunes a trained model."""
    return " ".join(f"--model init={p}" for p in init_model(kind))


rule train_vhat:
    input:
        tracking=TRACKING,
        init=init_model("vhat"),
    output:
        model=f"{RESULTS}/models/vhat.pt",
        loss=f"{RESULTS}/models/vhat_loss.csv",
        summary=f"{RESULTS}/models/vhat_train.json",
    params:
        init=init_arg("vhat"),
    threads: VF_THREADS
    log:
        f"{LOGS}/train_vhat.log",
    shell:
        "{PY} -m madpinn train-value --config {RESOLVED} --kind vhat --out {output.model} {params.init}"
        " --threads {threads} 2>&1 | tee {log}"


rule train_vs:
    input:
        tracking=TRACKING,
        init=init_model("vs"),
    output:
        model=f"{RESULTS}/models/vs.pt",
        loss=f"{RESULTS}/models/vs_loss.csv",
        summary=f"{RESULTS}/models/vs_train.json",
    params:
        init=init_arg("vs"),
    threads: VF_THREADS
    log:
        f"{LOGS}/train_vs.log",
    shell:
        "{PY} -m madpinn train-value --config {RESOLVED} --kind vs --out {output.model} {params.init}"
        " --threads {threads} 2>&1 | tee {log}"


rule validate_vs:
    input:
        tracking=TRACKING,
        model=rules.train_vs.output.model,
    output:
        report=f"{RESULTS}/validation/vs_rollouts.json",
        figure=multiext(f"{FIGURES}/fig_vs_slices", ".pdf", ".png"),
    params:
        stem=f"{FIGURES}/fig_vs_slices",
    threads: 1
    log:
        f"{LOGS}/validate_vs.log",
    shell:
        "{PY} -m madpinn validate-vs --config {RESOLVED} --model vs={input.model} --out {output.report}"
        " --fig-stem {params.stem} --threads {threads} 2>&1 | tee {log}"


rule validate_vhat:
    input:
        tracking=TRACKING,
        model=rules.train_vhat.output.model,
    output:
        report=f"{RESULTS}/validation/vhat_residuals.json",
    threads: 1
    log:
        f"{LOGS}/validate_vhat.log",
    shell:
        "{PY} -m madpinn validate-vhat --config {RESOLVED} --model vhat={input.model} --out {output.report}"
        " --threads {threads} 2>&1 | tee {log}"


rule fig_value_heatmap:
    input:
        tracking=TRACKING,
        model=rules.train_vhat.output.model,
    output:
        multiext(f"{FIGURES}/fig_value_heatmap", ".pdf", ".png"),
    params:
        stem=f"{FIGURES}/fig_value_heatmap",
    threads: 1
    log:
        f"{LOGS}/fig_value_heatmap.log",
    shell:
        "{PY} -m madpinn fig-value-heatmap --config {RESOLVED} --model vhat={input.model} --out-stem {params.stem}"
        " --threads {threads} 2>&1 | tee {log}"


EXTRA_TARGETS += [
    f"{RESULTS}/validation/vs_rollouts.json",
    f"{RESULTS}/validation/vhat_residuals.json",
    *[f"{FIGURES}/{name}.{ext}" for name in ("fig_value_heatmap", "fig_vs_slices") for ext in ("pdf", "png")],
]
