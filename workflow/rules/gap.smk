# Gap decomposition (issue 14): MAD-PINN with the same V̂ / V_s on the double integrator and on
# MuJoCo, each deployment fix alone and all together, on validation seeds. Not part of `all`:
#   snakemake -j1 gap_decomposition [--configfile workflow/configs/smoke.yaml]
GAP = config["gap_decomposition"]


rule gap_decomposition:
    input:
        vhat=rules.train_vhat.output.model,
        vs=rules.train_vs.output.model,
    output:
        csv=f"{RESULTS}/gap/decomposition.csv",
        md=f"{RESULTS}/gap/decomposition.md",
        json=f"{RESULTS}/gap/decomposition.json",
    params:
        agents=" ".join(str(n) for n in GAP["agent_counts"]),
        seeds=" ".join(str(s) for s in GAP["seeds"]),
        scenarios=GAP["scenarios"],
        sweep=(" --margin-sweep " + " ".join(str(m) for m in GAP["margin_sweep"])) if GAP["margin_sweep"] else "",
        out_dir=f"{RESULTS}/gap",
        hash=config_hash(GAP),
    threads: 1
    log:
        f"{LOGS}/gap_decomposition.log",
    shell:
        "{PY} -m madpinn gap-decomposition --config {RESOLVED} --model vhat={input.vhat} vs={input.vs} "
        "--agents {params.agents} --seeds {params.seeds} --scenarios {params.scenarios}{params.sweep} "
        "--out-dir {params.out_dir} --no-progress 2>&1 | tee {log}"
