# Collision readings (issue 38): every paper cell under each collision convention, from the base
# studies (pass-through: safety at r and 2r) and their `<base>_contacts` studies (contact physics).
# Defined when a contact study is configured (workflow/configs/collision_readings.yaml).
# Included after report.smk (TABLES complete) and before tables.smk.
from madpinn.evaluation.readings import CONTACTS_SUFFIX

_READING_TABLES = {n: s for n, (s, _) in TABLES.items() if s in config["studies"] and f"{s}{CONTACTS_SUFFIX}" in config["studies"]}

if _READING_TABLES:

    rule collision_readings:
        input:
            tracking=TRACKING,
            results=sorted({p for s in _READING_TABLES.values() for st in (s, f"{s}{CONTACTS_SUFFIX}") for p in study_results(st)}),
        output:
            csv=f"{FIGURES}/table_collision_readings.csv",
            md=f"{FIGURES}/table_collision_readings.md",
            html=report(f"{FIGURES}/table_collision_readings.html", caption="../report/table_collision_readings.rst",
                        category=REPORT_SECTIONS["our_tables"],
                        labels={"Item": "table_collision_readings", "Study": ", ".join(_READING_TABLES.values())}),
        params:
            config=RESOLVED,
            tables=[f"{n}={s}" for n, s in _READING_TABLES.items()],
            settings=settings_hash("experiment", extra={s: run_labels(s) for s in _READING_TABLES.values()}),
            source=source_hash("report"),
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

    EXTRA_TARGETS += [rules.collision_readings.output.csv, rules.collision_readings.output.md]
