# Agent models (issue 63, not in the paper): does passing over each other change safety and cost? A
# table of the cells of the studies `agent_models.studies` lists, each flying its own agent model
# (studies.<s>.agents; the 3-D double integrator's MAD-PINN run loads V̂ and V_s variants trained for
# it, rules train_vhat_variant / train_vs_variant) on the same scenarios as the planar study beside it.
# The evaluate rule computes the cells like any other; this job only builds the table. Defined when
# configured (workflow/configs/agent_models.yaml); not part of all:
#   snakemake -j2 table_agent_models --configfile workflow/configs/agent_models.yaml
if config["agent_models"]:
    AGENT_MODEL_STUDIES = config["agent_models"]["studies"]

    rule table_agent_models:
        input:
            tracking=TRACKING,
            results=studies_results(AGENT_MODEL_STUDIES),
        output:
            csv=kept(f"{FIGURES}/agent_models/table_agent_models.csv"),
            md=kept(f"{FIGURES}/agent_models/table_agent_models.md"),
            html=report(kept(f"{FIGURES}/agent_models/table_agent_models.html"), caption="../report/table_agent_models.rst",
                        category=REPORT_SECTIONS["our_tables"],
                        labels={"Item": "table_agent_models: 3-D double integrator (not in the paper)",
                                "Study": "agent_models.studies"}),
        params:
            config=RESOLVED,
            settings=settings_hash("agent-models"),
            source=source_hash("agent-models"),
            out_dir=out_dir_of("csv"),
        resources:
            mem_mb=2000,
            runtime=10,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/table_agent_models.log",
        shell:
            "python -m madpinn agent-models --config {params.config:q}"
            " --inputs {input.results:q} --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"
