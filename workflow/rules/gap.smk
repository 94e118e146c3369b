# Gap decomposition (issue 14): a table of the cells of the studies `gap_decomposition.studies`
# lists (MAD-PINN with the same V̂ / V_s on each backend, one deployment cause switched per run,
# validation seeds; studies.gap_*, `in_all: false`). The evaluate rule computes the cells like any
# other (cache, parallel cells, an MLflow run each); this job only builds the table, under
# paths.figures (the protocol's committed copy: paper_figures/gap_decomposition/). Not part of all:
#   snakemake -j2 gap_decomposition [--configfile workflow/configs/smoke.yaml]
if config["gap_decomposition"]:

    rule gap_decomposition:
        input:
            tracking=TRACKING,
            results=[p.replace(".parquet", ".json") for s in config["gap_decomposition"]["studies"]
                     for p in study_results(s)],
        output:
            csv=kept(f"{FIGURES}/gap_decomposition/decomposition.csv"),
            md=kept(f"{FIGURES}/gap_decomposition/decomposition.md"),
            json=kept(f"{FIGURES}/gap_decomposition/decomposition.json"),
        params:
            config=RESOLVED,
            out_dir=out_dir_of("csv"),
            settings=settings_hash("gap-decomposition"),
            source=source_hash("gap-decomposition"),
        resources:
            mem_mb=2000,
            runtime=10,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/gap_decomposition.log",
        shell:
            "python -m madpinn gap-decomposition --config {params.config:q} --inputs {input.results:q}"
            " --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"
