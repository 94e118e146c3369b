# DEF-MARL (issue 8): one training job per variant (defmarl-n3: 3 agents, defmarl-n8: 8 agents);
# evaluation jobs of run defmarl-<variant> depend on that variant's model only.
# CPU budget (paper config, 1 100 iterations, 1 thread): ~1 h per model on the 2-core CI-class machine
# (docs/reference/defmarl.md); smoke: seconds.
if "defmarl" in config["methods"]:
    DEFMARL_VARIANTS = sorted(config["methods"]["defmarl"]["variants"])
    for _v in DEFMARL_VARIANTS:
        register_models(f"defmarl-{_v}", lambda wildcards: {
            "policy": expand(rules.train_defmarl.output.model, variant=wildcards.run.partition("-")[2])[0]
        })

    rule train_defmarl:
        input:
            tracking=TRACKING,
        output:
            model=f"{RESULTS}/models/defmarl_{{variant}}.pt",
            history=f"{RESULTS}/models/defmarl_{{variant}}_history.csv",
            summary=f"{RESULTS}/models/defmarl_{{variant}}.json",
        wildcard_constraints:
            variant="|".join(DEFMARL_VARIANTS),
        params:
            config=RESOLVED,
            settings=settings_hash("train-defmarl", "variant"),
            source=source_hash("train-defmarl"),
        threads: 1
        resources:
            mem_mb=3000,
            runtime=150,   # 1 100 PPO iterations: 58-80 min on one core
            **TRAIN_GPU,
        priority: 50
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/train_defmarl_{{variant}}.log",
        shell:
            "python -m madpinn train-defmarl --config {params.config:q} --variant {wildcards.variant:q} --out {output.model:q}"
            " --threads {threads} 2>&1 | tee {log:q}"
