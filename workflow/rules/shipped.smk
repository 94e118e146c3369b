# Included after every training rule: each ruleorder below names a training rule that must exist.
# Shipped checkpoints (workflow/configs/shipped.yaml): results/models/<name>.pt comes from the
# sha256-checked models/<name>.pt instead of its training rule.
SHIPPED = config["shipped_models"]
if SHIPPED["enabled"] and SHIPPED["names"]:
    check_shipped_models(SHIPPED)   # before any job: a model trained for another config stops here

    # The model file is the only input and its manifest entry's sha256 a param: the job's provenance
    # hash (and so every cached evaluation cell downstream) depends on this model's bytes alone, so
    # re-shipping one model (which rewrites manifest.json) does not invalidate the cells of the others.
    rule install_shipped_model:
        input:
            model=f"{SHIPPED['dir']}/{{name}}.pt",
        output:
            f"{RESULTS}/models/{{name}}.pt",
        wildcard_constraints:
            name="|".join(SHIPPED["names"]),
        params:
            config=RESOLVED,
            dir=lambda w, input: os.path.dirname(input.model),   # = shipped_models.dir
            sha256=shipped_sha256,
        threads: 1
        priority: 100  # in place of a training: the cells that need the model wait for it
        resources:
            mem_mb=500,
            runtime=5,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/install_shipped_{{name}}.log",
        shell:
            "python -m madpinn install-shipped --config {params.config:q} --dir {params.dir:q} --name {wildcards.name:q}"
            " --out {output:q} 2>&1 | tee {log:q}"

    # one ruleorder per shipped name (a ruleorder naming a rule this configuration lacks disables it)
    if "vs" in SHIPPED["names"]:

        ruleorder: install_shipped_model > train_vs

    if "vhat" in SHIPPED["names"]:

        ruleorder: install_shipped_model > train_vhat

    if vhat_variants_used() and any(n.startswith("vhat_") for n in SHIPPED["names"]):   # rule train_vhat_variant exists

        ruleorder: install_shipped_model > train_vhat_variant

    if vf_variants_used("vs") and any(n.startswith("vs_") for n in SHIPPED["names"]):   # rule train_vs_variant exists

        ruleorder: install_shipped_model > train_vs_variant

    if "safemarl_nominal" in SHIPPED["names"]:

        ruleorder: install_shipped_model > train_safemarl_nominal

    if any(n.startswith("defmarl_") for n in SHIPPED["names"]):

        ruleorder: install_shipped_model > train_defmarl
