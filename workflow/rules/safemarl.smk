# SafeMARL (issue 7): train the nominal goal-reaching PPO policy once; evaluation jobs of the
# `safemarl` method (and its `safemarl-unfiltered` variant) depend on it and on the learned V_s.
from madpinn.config import config_hash


def _safemarl_train_hash():
    m = config["methods"]["safemarl"]
    return config_hash({"nominal": m["nominal"], "agents": config["agents"], "observation": config["observation"],
                        "arena": config["arenas"][m["nominal"]["arena"]], "dtype": config["dtype"]})


if "safemarl" in config["methods"]:
    METHOD_MODELS["safemarl"] = lambda wildcards: {"nominal": rules.train_safemarl_nominal.output.model,
                                                   "vs": rules.train_vs.output.model}

    rule train_safemarl_nominal:
        input:
            tracking=TRACKING,
        output:
            model=f"{RESULTS}/models/safemarl_nominal.pt",
            history=f"{RESULTS}/models/safemarl_nominal_history.csv",
            summary=f"{RESULTS}/models/safemarl_nominal.json",
        params:
            train_hash=_safemarl_train_hash(),
        threads: 1
        log:
            f"{LOGS}/train_safemarl_nominal.log",
        shell:
            "{PY} -m madpinn train-safemarl-nominal --config {RESOLVED} --out {output.model}"
            " --threads {threads} 2>&1 | tee {log}"

    # `all` trains the nominal policy when a study runs SafeMARL (filtered or not).
    if any(run.split("-")[0] == "safemarl" for st in config["studies"].values() for run in st["runs"]):
        EXTRA_TARGETS.append(rules.train_safemarl_nominal.output.model)
