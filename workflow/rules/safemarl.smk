# SafeMARL (issue 7): train the nominal goal-reaching PPO policy once; evaluation jobs of the
# `safemarl` method (and its `safemarl-unfiltered` variant) depend on it and on the learned V_s.

if "safemarl" in config["methods"]:
    # str(): a rules.X reference pins the producer to X; the shipped overlay's install rule may provide these
    register_models("safemarl", lambda wildcards: {"nominal": str(rules.train_safemarl_nominal.output.model),
                                                   "vs": str(rules.train_vs.output.model)})

    rule train_safemarl_nominal:
        input:
            tracking=TRACKING,
        output:
            model=f"{RESULTS}/models/safemarl_nominal.pt",
            history=f"{RESULTS}/models/safemarl_nominal_history.csv",
            summary=f"{RESULTS}/models/safemarl_nominal.json",
        params:
            config=RESOLVED,
            settings=settings_hash("train-safemarl-nominal"),
            source=source_hash("train-safemarl-nominal"),
        threads: 1
        resources:
            mem_mb=3000,
            runtime=60,
            **TRAIN_GPU,
        priority: 50
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/train_safemarl_nominal.log",
        shell:
            "python -m madpinn train-safemarl-nominal --config {params.config:q} --out {output.model:q}"
            " --threads {threads} 2>&1 | tee {log:q}"

    # `all` trains the nominal policy when a study it builds runs SafeMARL (filtered or not).
    if any(run.split("-")[0] == "safemarl" for s in studies_in_all() for run in config["studies"][s]["runs"]):
        register_targets(rules.train_safemarl_nominal.output.model)
