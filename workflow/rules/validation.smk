# Independent validation of the value functions (issue 15): V_s against a grid HJ solution
# (hj_reachability), V̂ by scenario-based verification in the exact 3-agent dynamics.


rule solve_vs_grid:
    input:
        tracking=TRACKING,
    output:
        solution=f"{RESULTS}/validation/vs_grid_solution.npz",
    threads: 2
    log:
        f"{LOGS}/solve_vs_grid.log",
    shell:
        "{PY} -m madpinn solve-vs-grid --config {RESOLVED} --out {output.solution} --no-progress 2>&1 | tee {log}"


rule validate_vs_grid:
    input:
        tracking=TRACKING,
        model=str(rules.train_vs.output.model),  # str(): a rules.X reference pins the producer to X (no shipped install)
        grid=rules.solve_vs_grid.output.solution,
    output:
        report=f"{RESULTS}/validation/vs_grid.json",
        figure=multiext(f"{FIGURES}/fig_vs_grid", ".pdf", ".png"),
    params:
        stem=f"{FIGURES}/fig_vs_grid",
    threads: 1
    log:
        f"{LOGS}/validate_vs_grid.log",
    shell:
        "{PY} -m madpinn validate-vs-grid --config {RESOLVED} --model {input.model} --grid {input.grid}"
        " --out {output.report} --fig-stem {params.stem} --threads {threads} 2>&1 | tee {log}"


EXTRA_TARGETS += [
    f"{RESULTS}/validation/vs_grid.json",
    *[f"{FIGURES}/fig_vs_grid.{ext}" for ext in ("pdf", "png")],
]


rule verify_vhat:
    input:
        tracking=TRACKING,
        model=str(rules.train_vhat.output.model),
    output:
        report=f"{RESULTS}/validation/vhat_scenario.json",
    threads: 1
    log:
        f"{LOGS}/verify_vhat.log",
    shell:
        "{PY} -m madpinn verify-vhat --config {RESOLVED} --model {input.model} --out {output.report}"
        " --threads {threads} 2>&1 | tee {log}"


EXTRA_TARGETS += [f"{RESULTS}/validation/vhat_scenario.json"]


# Shipped checkpoints (workflow/configs/shipped.yaml): results/models/<name>.pt comes from the
# sha256-checked models/<name>.pt instead of its training rule.
SHIPPED = config.get("shipped_models") or {}
if SHIPPED.get("enabled") and SHIPPED.get("names"):

    rule install_shipped_model:
        input:
            manifest=f"{SHIPPED['dir']}/manifest.json",
            model=f"{SHIPPED['dir']}/{{name}}.pt",
        output:
            f"{RESULTS}/models/{{name}}.pt",
        wildcard_constraints:
            name="|".join(SHIPPED["names"]),
        threads: 1
        log:
            f"{LOGS}/install_shipped_{{name}}.log",
        shell:
            "{PY} -m madpinn install-shipped --dir {SHIPPED[dir]} --name {wildcards.name} --out {output} 2>&1 | tee {log}"

    # one ruleorder per shipped name (a ruleorder naming a rule this configuration lacks disables it)
    if "vs" in SHIPPED["names"]:

        ruleorder: install_shipped_model > train_vs

    if "vhat" in SHIPPED["names"]:

        ruleorder: install_shipped_model > train_vhat

    if "safemarl_nominal" in SHIPPED["names"]:

        ruleorder: install_shipped_model > train_safemarl_nominal

    if any(n.startswith("defmarl_") for n in SHIPPED["names"]):

        ruleorder: install_shipped_model > train_defmarl
