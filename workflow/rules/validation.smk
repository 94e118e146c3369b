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
        model=rules.train_vs.output.model,
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
        model=rules.train_vhat.output.model,
    output:
        report=f"{RESULTS}/validation/vhat_scenario.json",
    threads: 1
    log:
        f"{LOGS}/verify_vhat.log",
    shell:
        "{PY} -m madpinn verify-vhat --config {RESOLVED} --model {input.model} --out {output.report}"
        " --threads {threads} 2>&1 | tee {log}"


EXTRA_TARGETS += [f"{RESULTS}/validation/vhat_scenario.json"]
