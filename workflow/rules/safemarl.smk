# SafeMARL (issue 7): train the nominal goal-reaching PPO policy once; evaluation jobs of the
# `safemarl` method (and its `safemarl-unfiltered` variant) depend on it and on the learned V_s.
SAFEMARL_NOMINAL = f"{RESULTS}/models/safemarl_nominal.pt"

if "safemarl" in config["methods"]:
    METHOD_INPUTS["safemarl"] = [SAFEMARL_NOMINAL, VS_MODEL]  # VS_MODEL: workflow/rules/train.smk

    rule train_safemarl_nominal:
        input:
            tracking=TRACKING,
        output:
            model=SAFEMARL_NOMINAL,
            history=f"{RESULTS}/models/safemarl_nominal_history.csv",
            summary=f"{RESULTS}/models/safemarl_nominal.json",
        params:
            config=RESOLVED,
            train_hash=safemarl_train_hash(),
            source=source_hash("marl"),
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

    # `all` trains the nominal policy when a study runs SafeMARL (filtered or not).
    if any(run.split("-")[0] == "safemarl" for st in config["studies"].values() for run in st["runs"]):
        EXTRA_TARGETS.append(SAFEMARL_NOMINAL)
