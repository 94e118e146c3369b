# Gap decomposition (issue 14): MAD-PINN with the same V̂ / V_s on the double integrator and on
# MuJoCo, each deployment fix alone and all together, on validation seeds. Not part of `all`:
#   snakemake -j1 gap_decomposition [--configfile workflow/configs/smoke.yaml]
GAP = config["gap_decomposition"]


rule gap_decomposition:
    input:
        vhat=str(rules.train_vhat.output.model),
        vs=str(rules.train_vs.output.model),
    output:
        csv=f"{RESULTS}/gap/decomposition.csv",
        md=f"{RESULTS}/gap/decomposition.md",
        json=f"{RESULTS}/gap/decomposition.json",
    params:
        config=RESOLVED,
        agents=[str(n) for n in GAP["agent_counts"]],
        seeds=[str(s) for s in GAP["seeds"]],
        scenarios=GAP["scenarios"],
        sweep=["--margin-sweep", *map(str, GAP["margin_sweep"])] if GAP["margin_sweep"] else [],
        out_dir=out_dir_of("csv"),
        settings=settings_hash("gap-decomposition"),
        source=source_hash("gap-decomposition", "madpinn"),
    threads: 1
    resources:
        mem_mb=4000,
        runtime=600,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/gap_decomposition.log",
    shell:
        "python -m madpinn gap-decomposition --config {params.config:q} --model vhat={input.vhat:q} --model vs={input.vs:q}"
        " --agents {params.agents:q} --seeds {params.seeds:q} --scenarios {params.scenarios:q} {params.sweep:q}"
        " --out-dir {params.out_dir:q} --no-progress 2>&1 | tee {log:q}"
