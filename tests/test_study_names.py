"""Every study the schema admits is a path the workflow can build: its name matches rule evaluate's
``study`` wildcard constraint (a study named outside it would be configured, validated, and
unreachable: ``MissingRuleException`` for each of its cells, as the scenario-law studies were)."""

import re

import yaml

from conftest import REPO


def test_every_schema_study_name_matches_the_study_wildcard():
    common = (REPO / "workflow" / "rules" / "common.smk").read_text()
    constraint = re.search(r'^\s+study=r"([^"]+)",$', common, re.M).group(1)
    schema = yaml.safe_load((REPO / "workflow" / "schemas" / "config.schema.yaml").read_text())
    names = list(schema["properties"]["studies"]["properties"])
    assert any(re.search(r"\d", n) for n in names)   # digits are in use (law_within_2m)
    assert [n for n in names if not re.fullmatch(constraint, n)] == []
