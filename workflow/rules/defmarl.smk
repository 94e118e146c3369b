# DEF-MARL (issue 8): one training job per variant (defmarl-n3: 3 agents, defmarl-n8: 8 agents);
# evaluation jobs of run defmarl-<variant> depend on that variant's model only.
# CPU budget (paper config, 550 iterations, 1 thread): ~20 min per model on the 2-core CI-class machine
# (docs/defmarl.md); smoke: seconds.
from madpinn.config import config_hash, method_config


def _defmarl_train_hash(wildcards):
    _, m = method_config(config, f"defmarl-{wildcards.variant}")
    return config_hash({"training": m["training"], "epigraph": m["epigraph"], "agents": config["agents"],
                        "observation": config["observation"], "arenas": config["arenas"], "dtype": config["dtype"]})


if "defmarl" in config["methods"]:
    DEFMARL_VARIANTS = sorted(config["methods"]["defmarl"]["variants"])
    for _v in DEFMARL_VARIANTS:
        METHOD_MODELS[f"defmarl-{_v}"] = lambda wildcards: {
            "policy": expand(rules.train_defmarl.output.model, variant=wildcards.run.partition("-")[2])[0]
        }

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
            train_hash=_defmarl_train_hash,
        threads: 1
        log:
            f"{LOGS}/train_defmarl_{{variant}}.log",
        shell:
            "{PY} -m madpinn train-defmarl --config {RESOLVED} --variant {wildcards.variant} --out {output.model}"
            " --threads {threads} 2>&1 | tee {log}"
