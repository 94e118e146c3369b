# DEF-MARL (issue 8): one training job per variant (defmarl-n3: 3 agents, defmarl-n8: 8 agents);
# evaluation jobs of run defmarl-<variant> depend on that variant's model only.
# CPU budget (paper config, 550 iterations, 1 thread): ~20 min per model on the 2-core CI-class machine
# (docs/defmarl.md); smoke: seconds.
# Helpers (defmarl_model, defmarl_train_hash): common.smk.
if "defmarl" in config["methods"]:
    DEFMARL_VARIANTS = sorted(config["methods"]["defmarl"]["variants"])
    for _v in DEFMARL_VARIANTS:
        if os.path.basename(defmarl_model(_v)) != f"defmarl_{_v}.pt":
            raise ValueError(f"methods.defmarl.variants.{_v}.model must be defmarl_{_v}.pt (the training rule's output)")
        METHOD_INPUTS[f"defmarl-{_v}"] = [defmarl_model(_v)]

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
            train_hash=defmarl_train_hash,
            source=source_hash("marl"),
        threads: 1
        resources:
            mem_mb=3000,
            runtime=90,
            **TRAIN_GPU,
        priority: 50
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/train_defmarl_{{variant}}.log",
        shell:
            "python -m madpinn train-defmarl --config {params.config:q} --variant {wildcards.variant:q} --out {output.model:q}"
            " --threads {threads} 2>&1 | tee {log:q}"
