"""The fast YAML path (libyaml's safe loader) reads every shipped YAML file as the pure-Python
safe loader does, and a broken file still gets the pure-Python loader's message."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from madpinn.config.yaml_text import parse_yaml

REPO = Path(__file__).resolve().parents[1]
SHIPPED = sorted({*REPO.glob("*.yaml"), *REPO.glob("workflow/**/*.yaml"), *REPO.glob("profiles/**/*.yaml"),
                  *REPO.glob("madpinn/**/*.yaml")})


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(REPO)))
def test_every_shipped_yaml_file_parses_as_the_pure_python_loader_does(path):
    text = path.read_text()
    assert parse_yaml(text) == yaml.safe_load(text)


def test_a_broken_file_gets_the_pure_python_loaders_error():
    text = "a: 1\n  b: [2\n"
    with pytest.raises(yaml.YAMLError) as fast:
        parse_yaml(text)
    with pytest.raises(yaml.YAMLError) as slow:
        yaml.safe_load(text)
    assert str(fast.value) == str(slow.value)
