# MAD-PINN policy (issue 4). Evaluation jobs of `madpinn[-variant]` run through rule `evaluate`
# (evaluate.smk) and load the value functions trained by train.smk; the two ablation tables of
# the paper are built from the ablation studies when those are configured.
# A run's settings may select a V̂ variant (`vhat: <name>`, trained by train_vhat_variant): madpinn_models (common.smk).
if "madpinn" in config["methods"]:
    register_models("madpinn", madpinn_models)

register_table("table_neighbour_ablation", "ablation_neighbours", "summary")
register_table("table_update_ablation", "ablation_update", "summary")
