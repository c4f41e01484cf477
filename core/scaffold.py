"""``frontal3d new-family``: a ready-to-install third-party family package.

The package uses exactly the mechanism the built-in families use (an entry point in
the ``frontal3d`` group), so after ``pip install -e`` it is listed by
``frontal3d families`` and reconstructs like a built-in one.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from frontal3d import __version__
from frontal3d.errors import ConfigError

_NAME = re.compile(r"^[a-z][a-z0-9_]{1,30}$")

_PYPROJECT = """\
[build-system]
requires = ["setuptools>=68"]
build-backend = "setuptools.build_meta"

[project]
name = "frontal3d-{dist}"
version = "0.1.0"
description = "The {name} family for frontal3d."
requires-python = ">=3.11"
dependencies = ["frontal3d>={version}"]

[project.entry-points.frontal3d]
{name} = "frontal3d_{name}"

[tool.setuptools]
packages = ["frontal3d_{name}"]

[tool.setuptools.package-data]
frontal3d_{name} = ["*.yaml", "*.glb"]
"""

_INIT = '''\
"""The {name} family: a frontal3d plugin.

Registered through the ``frontal3d`` entry point in pyproject.toml. Edit family.yaml
for the family's data and template.py for its template; see frontal3d's docs/plugins.md
for every hook you can add (segmenters, classifiers, back-texture and symmetry rules).
"""

from pathlib import Path

from frontal3d import hookimpl
from frontal3d.family import Family, Template, load_family_yaml, template_for

from frontal3d_{name}.template import BUILDERS, REGIONS

FAMILY = load_family_yaml(Path(__file__).with_name("family.yaml"), REGIONS)


@hookimpl
def frontal3d_register_families() -> list[Family]:
    return [FAMILY]


@hookimpl
def frontal3d_template(family: Family, subtype: str, settings: dict) -> Template | None:
    if family.name != FAMILY.name:
        return None
    return template_for(FAMILY, BUILDERS, subtype, settings)
'''

_FAMILY_YAML = """\
# The {name} family. Canonical frame: the camera looks along -Z, image right = +X, up = +Y.
name: {name}
description: {title} seen from the {view}.
canonical_view: {view}
view_hint: a {view} view of the {name}
real_size:   # typical longest bounding-box edge, metres, per subtype
  default: 1.0
settings:
  back_texture: mirror_front      # or synthesize_from_region with back_texture_params {{region: body}}
  symmetry: none                  # or mirror_z when the hidden side mirrors the visible one
  max_angle_deg: 180.0
"""

_TEMPLATE_BUILT = '''\
"""The {name} template, built by code: a rounded slab to start from.

Replace it with a mesh of your own (`frontal3d new-family {name} --template MESH`)
or build a better one here with manifold3d. Region 0 should be the main body.
"""

import manifold3d
import numpy as np
import trimesh

from frontal3d.family import Template

REGIONS = {{"default": ("body",)}}


def build_default() -> Template:
    """A 1.0 x 0.6 m rounded slab, 0.2 m deep: a neutral start for any object."""
    outline = manifold3d.CrossSection.square((0.8, 0.4), center=True).offset(0.1, manifold3d.JoinType.Round, circular_segments=48)
    slab = manifold3d.Manifold.extrude(outline, 0.2).translate((0.0, 0.0, -0.1))
    mesh = slab.to_mesh()
    tm = trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts), process=True)
    return Template(
        family="{name}", subtype="default", mesh=tm,
        face_regions=np.zeros(len(tm.faces), dtype=np.int32), region_names=REGIONS["default"],
        landmarks={{"center": np.zeros(3)}},
    )


BUILDERS = {{"default": build_default}}
'''

_TEMPLATE_MESH = '''\
"""The {name} template: the mesh shipped in this package (template.glb)."""

from pathlib import Path

from frontal3d.family import Template

REGIONS = {{"default": {regions!r}}}


def build_default() -> Template:
    """Load template.glb through frontal3d's checks (watertight, orientation, regions)."""
    from frontal3d_{name} import FAMILY
    from frontal3d.template_tools import template_from_mesh

    template, _warnings = template_from_mesh(Path(__file__).with_name("template.glb"), FAMILY, "default")
    return template


BUILDERS = {{"default": build_default}}
'''

_TEST = '''\
"""The {name} family is installed, listed and has a usable template."""

from frontal3d.plugins import Plugins


def test_family_is_registered_through_its_entry_point():
    plugins = Plugins()
    family = plugins.family("{name}")
    assert family.subtypes == ("default",)


def test_template_is_watertight_and_labelled():
    plugins = Plugins()
    family = plugins.family("{name}")
    template = plugins.hook.frontal3d_template(family=family, subtype="default", settings=plugins.settings("{name}"))
    assert template.mesh.is_watertight
    assert len(template.face_regions) == len(template.mesh.faces)
'''

_README = """\
# frontal3d-{dist}

The `{name}` family for [frontal3d](https://example.invalid/frontal3d): reconstruct a {name}
from one {view} photo.

    pip install -e .
    frontal3d families            # lists {name}
    frontal3d reconstruct photo.jpg --family {name} -o out/
    python -m pytest tests

Edit `frontal3d_{name}/family.yaml` (view, sizes, settings) and `frontal3d_{name}/template.py`
(the template). frontal3d's docs/plugins.md describes every hook.
"""


def scaffold_family(name: str, out_dir: Path, view: str = "front", template_mesh: Path | None = None) -> Path:
    """Write the package for family ``name`` into ``out_dir`` (which must not exist)."""
    if not _NAME.match(name):
        raise ConfigError(f"family name {name!r}: use 2-31 lower-case letters, digits or _, starting with a letter")
    if out_dir.exists():
        raise ConfigError(f"{out_dir} already exists: choose another folder with -o")
    if template_mesh is not None and not template_mesh.is_file():
        raise ConfigError(f"template mesh not found: {template_mesh}")
    package = out_dir / f"frontal3d_{name}"
    fields = {"name": name, "dist": name.replace("_", "-"), "view": view, "title": name.replace("_", " ").capitalize(), "version": __version__}
    package.mkdir(parents=True)
    (out_dir / "tests").mkdir()
    (out_dir / "pyproject.toml").write_text(_PYPROJECT.format(**fields))
    (out_dir / "README.md").write_text(_README.format(**fields))
    (package / "__init__.py").write_text(_INIT.format(**fields))
    (package / "family.yaml").write_text(_FAMILY_YAML.format(**fields))
    if template_mesh is None:
        (package / "template.py").write_text(_TEMPLATE_BUILT.format(**fields))
    else:
        _write_mesh_as_glb(template_mesh, package / "template.glb")
        (package / "template.py").write_text(_TEMPLATE_MESH.format(regions=("body",), **fields))
    (out_dir / "tests" / f"test_{name}.py").write_text(_TEST.format(**fields))
    return out_dir


def _write_mesh_as_glb(source: Path, target: Path) -> None:
    if source.suffix.lower() == ".glb":
        shutil.copyfile(source, target)
        return
    import trimesh

    trimesh.load(source, force="scene").export(target)
