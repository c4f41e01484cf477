"""What ``frontal3d families`` lists: each family with its templates' regions and landmarks."""

from __future__ import annotations

from typing import Any

from frontal3d.errors import Frontal3DError
from frontal3d.plugins import Plugins


def family_catalogue(plugins: Plugins) -> list[dict[str, Any]]:
    """Every installed family as plain data, with the landmarks of each subtype's template.

    A template that fails to build is listed with its error instead of hiding the family.
    """
    catalogue = []
    for family in plugins.families.values():
        entry = family.to_dict()
        entry["plugin"] = _plugin_of(plugins, family.name)
        entry["landmarks"] = {}
        entry["template_errors"] = {}
        settings = plugins.settings(family.name)
        for subtype in family.subtypes:
            try:
                template = plugins.hook.frontal3d_template(family=family, subtype=subtype, settings=settings)
            except Frontal3DError as exc:
                entry["template_errors"][subtype] = str(exc)
                continue
            if template is not None:
                entry["landmarks"][subtype] = sorted(template.landmarks)
        catalogue.append(entry)
    return catalogue


def _plugin_of(plugins: Plugins, family_name: str) -> str | None:
    for impl in plugins.hook.frontal3d_register_families.get_hookimpls():
        if any(f.name == family_name for f in impl.function() or []):
            return impl.plugin_name
    return None
