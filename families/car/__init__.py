"""The built-in car family: a frontal3d plugin like any third-party one.

It registers through the ``frontal3d`` entry point in pyproject.toml; its data
lives in family.yaml and its templates are built by code in template.py.
"""

from pathlib import Path

from frontal3d import hookimpl
from frontal3d.family import Family, Template, load_family_yaml, template_for

from frontal3d_car.template import BUILDERS, REGIONS

FAMILY = load_family_yaml(Path(__file__).with_name("family.yaml"), REGIONS)


@hookimpl
def frontal3d_register_families() -> list[Family]:
    return [FAMILY]


@hookimpl
def frontal3d_template(family: Family, subtype: str, settings: dict) -> Template | None:
    if family.name != FAMILY.name:
        return None
    return template_for(FAMILY, BUILDERS, subtype, settings)
