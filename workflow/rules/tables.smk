# Paper tables, each its own target (e.g. `snakemake -j2 table_safety_scaling`); the rule of each is
# defined by register_table (common.smk), also for the tables other rule files register (the
# ablations in madpinn.smk, the structured conflicts in conflicts.smk). The order of registration
# is only the order in which the reproduction report lists the tables.
register_table("table_safety_scaling", "main", "safety_by_n")
register_table("table_ours_scaling", "scaling", "summary")
