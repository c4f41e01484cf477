"""The plugin machinery: discovery, plugins.toml, the allow-list and loud failures."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest

from frontal3d.cli import main
from frontal3d.config import Config, load_config
from frontal3d.errors import ConfigError, PluginError
from frontal3d.plugins import Plugins

BUILT_IN = {"guitar", "car", "airplane"}

TOY_PLUGIN = '''
import numpy as np
import trimesh
from frontal3d import hookimpl
from frontal3d.family import Family, Template

FAMILY = Family(name="{family}", subtypes=("plain",), canonical_view="front",
                regions={{"plain": ("body",)}}, real_size={{"plain": 0.3}})

@hookimpl
def frontal3d_register_families():
    return [FAMILY]

@hookimpl
def frontal3d_template(family, subtype, settings):
    if family.name != FAMILY.name:
        return None
    mesh = trimesh.creation.box((0.3, 0.2, 0.05))
    return Template(family=family.name, subtype=subtype, mesh=mesh,
                    face_regions=np.zeros(len(mesh.faces), int), region_names=("body",))
'''


def _fake_distribution(root: Path, dist: str, entry_name: str, module: str, source: str) -> None:
    """A real installed distribution (dist-info with entry_points.txt) on a path we add to sys.path."""
    (root / f"{module}.py").write_text(source)
    info = root / f"{dist.replace('-', '_')}-1.2.3.dist-info"  # as pip names it: name, dash, version
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 1.2.3\n")
    (info / "entry_points.txt").write_text(f"[frontal3d]\n{entry_name} = {module}\n")


@pytest.fixture
def toy_site(tmp_path, monkeypatch):
    site = tmp_path / "site"
    site.mkdir()
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.chdir(tmp_path)  # no ./plugins.toml: every installed plugin loads
    return site


def test_built_in_families_come_through_entry_points():
    plugins = Plugins()
    assert BUILT_IN <= set(plugins.families)
    sources = {info.name: info.source for info in plugins.infos}
    for name in BUILT_IN:
        assert sources[name].startswith("entry point")
    assert plugins.families["car"].canonical_view == "side"
    assert plugins.families["airplane"].canonical_view == "top"
    assert plugins.families["guitar"].canonical_view == "front"


def test_third_party_family_is_discovered_by_entry_point(toy_site):
    _fake_distribution(toy_site, "frontal3d-box", "box", "frontal3d_box_toy", TOY_PLUGIN.format(family="box"))
    plugins = Plugins()
    assert "box" in plugins.families
    info = next(i for i in plugins.infos if i.name == "box")
    assert info.version == "1.2.3"
    assert "frontal3d_template" in info.hooks


def test_allow_list_environment_variable(toy_site, monkeypatch):
    _fake_distribution(toy_site, "frontal3d-box", "box", "frontal3d_box_toy2", TOY_PLUGIN.format(family="box"))
    monkeypatch.setenv("FRONTAL3D_LOAD_PLUGINS", "car,box")
    plugins = Plugins()
    assert set(plugins.families) == {"car", "box"}
    monkeypatch.setenv("FRONTAL3D_LOAD_PLUGINS", "")
    assert Plugins().families == {}


def test_misspelled_hook_fails_loudly(toy_site):
    source = TOY_PLUGIN.format(family="typo") + "\n@hookimpl\ndef frontal3d_templat(family, subtype, settings):\n    return None\n"
    _fake_distribution(toy_site, "frontal3d-typo", "typo", "frontal3d_typo_toy", source)
    with pytest.raises(PluginError, match="typo.*frontal3d_templat"):
        Plugins()


def test_broken_plugin_is_reported_by_name_without_hiding_others(toy_site):
    _fake_distribution(toy_site, "frontal3d-broken", "broken", "frontal3d_broken_toy", "import no_such_module_xyz\n")
    plugins = Plugins()
    broken = {info.name: info.error for info in plugins.broken}
    assert "broken" in broken and "no_such_module_xyz" in broken["broken"]
    assert BUILT_IN <= set(plugins.families)


def test_broken_plugin_shows_in_cli_listing(toy_site, capsys):
    _fake_distribution(toy_site, "frontal3d-broken", "broken", "frontal3d_broken_toy2", "raise RuntimeError('boom')\n")
    assert main(["plugins", "--json"]) == 0
    captured = capsys.readouterr()
    listed = {p["name"]: p for p in json.loads(captured.out)}
    assert "boom" in listed["broken"]["error"]
    assert "plugin broken not loaded" in captured.err
    assert "frontal3d_register_families" in listed["car"]["hooks"]


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "plugins.toml"
    path.write_text(textwrap.dedent(text))
    return path


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[plugin]\nenabled = []\n", r"plugins.toml: plugin: unknown key"),
        ("[plugins]\nenable = ['car']\n", r"plugins.enable: unknown key"),
        ("[plugins]\nenabled = 'car'\n", r"plugins.enabled must be a list"),
        ("[plugins]\nenabled = ['car', 'boat']\n", r"plugins.enabled: unknown plugin\(s\) boat"),
        ("[families.car]\nworking_resolutoin = 300\n", r"families.car.working_resolutoin: unknown setting"),
        ("[families.car]\nworking_resolution = 'big'\n", r"families.car.working_resolution: expected int"),
        ("[families.car]\nmax_texture_side = -1\n", r"families.car.max_texture_side: must be at least 0"),
        ("[plugins\n", r"not valid TOML"),
    ],
)
def test_plugins_toml_errors_name_file_and_key(tmp_path, text, message):
    path = _write(tmp_path, text)
    with pytest.raises(ConfigError, match=message):
        plugins = Plugins(load_config(path))
        plugins.settings("car")


def test_plugins_toml_order_settings_and_local_module(tmp_path):
    (tmp_path / "mug_plugin.py").write_text(TOY_PLUGIN.format(family="mug"))
    path = _write(
        tmp_path,
        """
        [plugins]
        enabled = ["car", "guitar"]
        modules = ["mug_plugin.py"]
        [families.car]
        working_resolution = 300
        frontal_threshold = 1
        """,
    )
    plugins = Plugins(load_config(path))
    assert set(plugins.families) == {"car", "guitar", "mug"}
    settings = plugins.settings("car")
    assert settings["working_resolution"] == 300
    assert settings["frontal_threshold"] == 1.0 and isinstance(settings["frontal_threshold"], float)
    assert settings["symmetry"] == "mirror_z"  # the family's own default survives
    assert plugins.settings("guitar")["working_resolution"] == 350
    sources = {info.name: info.source for info in plugins.infos}
    assert sources["mug_plugin"].startswith("plugins.toml")


def test_repository_plugins_toml_is_valid():
    path = Path(__file__).resolve().parents[1] / "plugins.toml"
    plugins = Plugins(load_config(path))
    for name in BUILT_IN:
        plugins.settings(name)


def test_unknown_family_is_a_clear_error():
    from frontal3d.errors import UnknownFamilyError

    with pytest.raises(UnknownFamilyError, match=r"unknown family 'boat' \(installed: .*car"):
        Plugins(Config()).family("boat")
