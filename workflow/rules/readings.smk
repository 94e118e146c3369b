# Collision readings (issue 38): every paper cell under each collision convention, from the base
# studies (pass-through: safety at r and 2r) and their `<base>_contacts` studies (contact physics).
# Defined when a contact study is configured (workflow/configs/collision_readings.yaml); its inputs
# are functions of the registered tables, so the include order does not matter.
# reading_tables / reading_studies: common.smk.
from madpinn.evaluation.contact_studies import CONTACTS_SUFFIX

if any(s.endswith(CONTACTS_SUFFIX) for s in config["studies"]):

    rule collision_readings:
        input:
            tracking=TRACKING,
            results=lambda w: studies_results(reading_studies()),
        output:
            csv=kept(f"{FIGURES}/table_collision_readings.csv"),
            md=kept(f"{FIGURES}/table_collision_readings.md"),
            html=report(kept(f"{FIGURES}/table_collision_readings.html"), caption="../report/table_collision_readings.rst",
                        category=REPORT_SECTIONS["our_tables"],
                        labels={"Item": "table_collision_readings", "Study": "base studies and their _contacts readings"}),
        params:
            config=RESOLVED,
            tables=lambda w: [f"{n}={s}" for n, s in reading_tables().items()],
            settings=settings_hash("collision-readings", studies=reading_studies),
            source=source_hash("collision-readings"),
            out_dir=out_dir_of("csv"),
        resources:
            mem_mb=2000,
            runtime=10,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/collision_readings.log",
        shell:
            "python -m madpinn collision-readings --config {params.config:q} --tables {params.tables:q}"
            " --inputs {input.results:q} --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"

    register_targets(rules.collision_readings.output.csv, rules.collision_readings.output.md)


# Controller readings (issue 46): the ctl_* studies, one per (arena, sim.mujoco.controller).
CONTROLLER_STUDIES = [s for s in config["studies"] if s.startswith("ctl_")]
if CONTROLLER_STUDIES:

    rule controller_readings:
        input:
            tracking=TRACKING,
            results=lambda w: studies_results(CONTROLLER_STUDIES),
        output:
            csv=kept(f"{FIGURES}/table_controller_readings.csv"),
            md=kept(f"{FIGURES}/table_controller_readings.md"),
            html=report(kept(f"{FIGURES}/table_controller_readings.html"), caption="../report/table_controller_readings.rst",
                        category=REPORT_SECTIONS["our_tables"],
                        labels={"Item": "table_controller_readings", "Study": "ctl_* studies"}),
        params:
            config=RESOLVED,
            settings=settings_hash("controller-readings", studies=CONTROLLER_STUDIES),
            source=source_hash("controller-readings"),
            out_dir=out_dir_of("csv"),
        resources:
            mem_mb=2000,
            runtime=10,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/controller_readings.log",
        shell:
            "python -m madpinn controller-readings --config {params.config:q}"
            " --inputs {input.results:q} --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"

    if all(s in studies_in_all() for s in CONTROLLER_STUDIES):
        register_targets(rules.controller_readings.output.csv, rules.controller_readings.output.md)


# Table II under the readings the paper leaves open (issue 60): every (study, run, horizon) of the
# studies table_ii_readings lists, judged against Table II by the pre-registered scale, the claim's
# verdict, and the start/goal laws against Table I's anchor. Defined when configured
# (workflow/configs/scenario_laws.yaml); not part of all:  snakemake -j2 table_ii_readings
if config["table_ii_readings"]:
    TABLE_II_STUDIES = [*config["table_ii_readings"]["studies"], *config["table_ii_readings"]["baselines"],
                        config["table_ii_readings"]["anchor"]["study"]]
    # the readings page (validation seeds) these readings were chosen on: an input, so a new one reruns this page
    from madpinn.config.paths import in_repository

    TABLE_II_CHOSEN_ON = [str(in_repository(config["table_ii_readings"]["chosen_on"]))] if config["table_ii_readings"]["chosen_on"] else []

    rule table_ii_readings:
        input:
            tracking=TRACKING,
            results=studies_results(TABLE_II_STUDIES),
            chosen_on=TABLE_II_CHOSEN_ON,
        output:
            csv=kept(f"{FIGURES}/table_ii_readings/table_ii_readings.csv"),
            md=kept(f"{FIGURES}/table_ii_readings/table_ii_readings.md"),
            html=report(kept(f"{FIGURES}/table_ii_readings/table_ii_readings.html"), caption="../report/table_ii_readings.rst",
                        category=REPORT_SECTIONS["our_tables"],
                        labels={"Item": "table_ii_readings", "Study": "table_ii_readings.studies"}),
            verdict=kept(f"{FIGURES}/table_ii_readings/verdict.json"),
            laws=kept(f"{FIGURES}/table_ii_readings/laws.csv"),
            png=report(kept(f"{FIGURES}/table_ii_readings/fig_table_ii_readings.png"), caption="../report/table_ii_readings.rst",
                       category=REPORT_SECTIONS["our_tables"],
                       labels={"Item": "fig_table_ii_readings", "Study": "table_ii_readings.studies"}),
            pdf=kept(f"{FIGURES}/table_ii_readings/fig_table_ii_readings.pdf"),
            laws_png=report(kept(f"{FIGURES}/table_ii_readings/fig_scenario_laws.png"), caption="../report/table_ii_readings.rst",
                            category=REPORT_SECTIONS["our_tables"],
                            labels={"Item": "fig_scenario_laws", "Study": "table_ii_readings.studies"}),
            laws_pdf=kept(f"{FIGURES}/table_ii_readings/fig_scenario_laws.pdf"),
        params:
            config=RESOLVED,
            settings=settings_hash("table-ii-readings"),
            source=source_hash("table-ii-readings"),
            out_dir=out_dir_of("csv"),
        resources:
            mem_mb=2000,
            runtime=10,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/table_ii_readings.log",
        shell:
            "python -m madpinn table-ii-readings --config {params.config:q}"
            " --inputs {input.results:q} --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"


# V̂'s recipe re-chosen on validation seeds (issue 61 item 4): per deciding cell the training band over
# the base and its training-seed replicates, each component's verdict and the action the rule fixed
# before the cells (docs/findings/2026-11-29-vhat-recipe-preregistered.md). Defined when configured
# (workflow/configs/vhat_recipe.yaml); not part of all:  snakemake -j2 vhat_recipe
if config["vhat_recipe"]:
    from madpinn.evaluation.recipe_settings import RecipeSettings

    try:   # the section's cross-field rules (madpinn/evaluation/recipe_settings.py), before any job
        RecipeSettings.from_config(config)
    except Exception as exc:
        stop_workflow(exc)
    RECIPE_STUDIES = list(dict.fromkeys([*config["vhat_recipe"]["deciding"], *config["vhat_recipe"]["reported"]]))

    rule vhat_recipe:
        input:
            tracking=TRACKING,
            results=studies_results(RECIPE_STUDIES),
        output:
            csv=kept(f"{FIGURES}/vhat_recipe/vhat_recipe.csv"),
            md=kept(f"{FIGURES}/vhat_recipe/vhat_recipe.md"),
            json=kept(f"{FIGURES}/vhat_recipe/vhat_recipe.json"),
        params:
            config=RESOLVED,
            settings=settings_hash("vhat-recipe"),
            source=source_hash("vhat-recipe"),
            out_dir=out_dir_of("csv"),
        resources:
            mem_mb=2000,
            runtime=10,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/vhat_recipe.log",
        shell:
            "python -m madpinn vhat-recipe --config {params.config:q}"
            " --inputs {input.results:q} --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"
