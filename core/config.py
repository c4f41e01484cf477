"""plugins.toml: which plugins load, in what order, and per-family settings.

Every mistake in the file (unknown section or key, wrong type, unknown plugin) is a
:class:`ConfigError` naming the file and the key, so a typo never passes silently.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from frontal3d.errors import ConfigError

#: Environment variable naming the plugins.toml to use (else ./plugins.toml).
CONFIG_ENV = "FRONTAL3D_CONFIG"

#: Settings every family has; a family's own defaults override these, and
#: plugins.toml overrides both. A key not here nor in the family's defaults is an error.
CORE_FAMILY_SETTINGS: dict[str, Any] = {
    "working_resolution": 350,  # long side, in pixels, of the shape stages' grid (the paper: at most 350)
    "template_resolution": 512,  # side of the template's front/back renders
    "boundary_k": 0,  # DP jump bound k of eq. (2); 0 = scale the paper's 128 @ 350 px with resolution
    "region_k": 32,  # the per-region jump bound K of section 3.2.2
    "max_angle_deg": 180.0,  # in-plane rotation searched by the alignment
    "frontal_threshold": 0.45,  # minimum silhouette agreement (IoU x foreshortening) of the frontal gate
    "template_past_box": False,  # silhouette agreement counts the template placed past the object's box (plus a 10 % margin) as missed, not only within it
    "shape_prior": False,  # cut GrabCut's mask again with the templates placed on it (2-3 s; helps cluttered backgrounds)
    "mirror_repair": False,  # cut pieces of the segmented mask that break the object's mirror symmetry against background, add back a missing mirror half (canonical views symmetric about a line)
    "mirror_repair_cuts_own_colour": True,  # the mirror repair also cuts an object-coloured piece where the learned segmenter doubts it (a blob of a plane's own grey); false where the object's own parts break its symmetry (a guitar's horns)
    "mirror_repair_paired_colours": False,  # the mirror repair reads the object's colours only where both sides of the line look alike (a flat face lit evenly; not a plane's dihedral wings)
    "turned_margin": 1.0,  # frontal gate: reject when a template turned 30-90 deg fits the outline better by more than this IoU; 1 = off
    "mirror_margin": 1.0,  # frontal gate: reject when the outline is less mirror-symmetric about its axis than the template's by more than this IoU; 1 = off
    "contact_pair_margin": 1.0,  # frontal gate: reject when both axles' ground contacts split into pairs further apart than this share of the length; 1 = off
    "underside_margin": 1.0,  # frontal gate: reject when the outline's bottom between the wheels shows a dark band (a floor) taller than this share of the length; 1 = off
    "parallax_margin": 1.0,  # frontal gate: reject when the neck runs beside the body's midline by more than this share of the body's width; 1 = off
    "rim_margin": 1.0,  # frontal gate: reject when the body shows a side-wall band along one side wider than along the opposite side by more than this share of the body's width; 1 = off
    "neck_wall_margin": 1.0,  # frontal gate: reject when the neck's offset from the body's midline and the left-right side-wall gap agree on one turn about the neck and average more than this share of their own margins (parallax_margin, rim_margin); 1 = off
    "neckless_margin": 1.0,  # frontal gate: reject when across more than this share of the placed template's lower-neck rows the outline shows no neck (nothing, or over 1.5 necks wide): its body fits, but nothing there is a neck; 1 = off
    "fill_holes": True,  # fill the small holes the core segmenters leave where the placed template is solid (a chrome hub taken for a white backdrop)
    "max_rebuilt_share": 0.5,  # refuse a reconstruction whose front would be rebuilt from the template over more than this share, behind detected people or occluders (not the user's --occluder-mask); 1 = off
    "outline_mirror": False,  # rebuild a hidden outline (and judge people in front) by the object's mirror image where that is seen and fits better than the template
    "depth_scale": "global",  # local, smooth, global or length (the object's length): how depth follows the warp
    "smooth_iterations": 10,  # Laplacian smoothing passes of the mesh
    "max_vertices": 0,  # 0 = keep every pixel's vertex
    "symmetry": "none",  # name of a symmetry rule
    "back_texture": "mirror_front",  # name of a back-texture rule
    "back_texture_params": {},  # passed to the back-texture rule
    "bump_strength": 1.0,  # normal-map strength from texture derivatives
    "max_texture_side": 8192,  # longest side of the texture atlas in pixels (front and back side by side); larger photos are textured at a lower resolution; 0 = the photo's full resolution
    "size_m": 0.0,  # longest side of the output in metres; 0 = the template's real size
    "template_path": "",  # a user mesh to use instead of the built-in template
    "weights": {},  # learned-model checkpoints by model name (segmenter, frontal, subtype, regions)
}

_PLUGINS_KEYS = {"enabled", "disabled", "modules"}
_TOP_KEYS = {"plugins", "families", "core"}
_CORE_KEYS = {"cache_dir"}


@dataclass
class Config:
    """The parsed, validated content of plugins.toml (empty when there is none)."""

    path: Path | None = None
    enabled: list[str] | None = None
    disabled: list[str] = field(default_factory=list)
    modules: list[Path] = field(default_factory=list)
    family_settings: dict[str, dict[str, Any]] = field(default_factory=dict)
    cache_dir: Path | None = None

    def where(self, key: str) -> str:
        """How to name a key in an error message: 'plugins.toml: families.car.symmetry'."""
        return f"{self.path or 'plugins.toml'}: {key}"


def find_config_path(explicit: Path | None = None) -> Path | None:
    """The plugins.toml in force: --config, then $FRONTAL3D_CONFIG, then ./plugins.toml."""
    if explicit is not None:
        if not explicit.is_file():
            raise ConfigError(f"config file not found: {explicit}")
        return explicit
    env = os.environ.get(CONFIG_ENV)
    if env:
        path = Path(env)
        if not path.is_file():
            raise ConfigError(f"{CONFIG_ENV} points at a missing file: {path}")
        return path
    local = Path.cwd() / "plugins.toml"
    return local if local.is_file() else None


def load_config(path: Path | None) -> Config:
    """Parse and structurally validate plugins.toml; family keys are checked later."""
    if path is None:
        return Config()
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read: {exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from exc
    config = Config(path=path)
    _check_keys(config, data, _TOP_KEYS, "")
    plugins = _table(config, data, "plugins")
    _check_keys(config, plugins, _PLUGINS_KEYS, "plugins.")
    if "enabled" in plugins:
        config.enabled = _string_list(config, plugins["enabled"], "plugins.enabled")
    config.disabled = _string_list(config, plugins.get("disabled", []), "plugins.disabled")
    modules = _string_list(config, plugins.get("modules", []), "plugins.modules")
    config.modules = [(path.parent / m).resolve() for m in modules]
    core = _table(config, data, "core")
    _check_keys(config, core, _CORE_KEYS, "core.")
    if "cache_dir" in core:
        if not isinstance(core["cache_dir"], str):
            raise ConfigError(f"{config.where('core.cache_dir')} must be a string path")
        config.cache_dir = (path.parent / core["cache_dir"]).resolve()
    families = _table(config, data, "families")
    for name, table in families.items():
        if not isinstance(table, dict):
            raise ConfigError(f"{config.where(f'families.{name}')} must be a table of settings")
        config.family_settings[name] = dict(table)
    return config


def merge_family_settings(config: Config, family_name: str, family_defaults: dict[str, Any]) -> dict[str, Any]:
    """Core defaults < family defaults < plugins.toml, with every key and type checked."""
    merged = {**CORE_FAMILY_SETTINGS, **family_defaults}
    for key, value in config.family_settings.get(family_name, {}).items():
        where = config.where(f"families.{family_name}.{key}")
        if key not in merged:
            known = ", ".join(sorted(merged))
            raise ConfigError(f"{where}: unknown setting (known: {known})")
        merged[key] = coerce_setting(value, merged[key], where, key)
    return merged


#: The smallest value a numeric setting may take (below it the pipeline could only fail later, less clearly).
SETTING_MINIMA: dict[str, int] = {
    "working_resolution": 16,
    "template_resolution": 32,
    "boundary_k": 0,
    "region_k": 0,
    "smooth_iterations": 0,
    "max_vertices": 0,
    "max_texture_side": 0,
}


def coerce_setting(value: Any, default: Any, where: str, key: str = "") -> Any:
    """Accept a value of the default's type (an int where a float is expected too), within :data:`SETTING_MINIMA`."""
    if isinstance(default, bool):
        ok = isinstance(value, bool)
    elif isinstance(default, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        value = float(value) if ok else value
    elif isinstance(default, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
    else:
        ok = isinstance(value, type(default))
    if not ok:
        raise ConfigError(f"{where}: expected {type(default).__name__}, got {type(value).__name__} {value!r}")
    if key in SETTING_MINIMA and value < SETTING_MINIMA[key]:
        raise ConfigError(f"{where}: must be at least {SETTING_MINIMA[key]}, got {value!r}")
    return value


def _table(config: Config, data: dict[str, Any], key: str) -> dict[str, Any]:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise ConfigError(f"{config.where(key)} must be a table")
    return value


def _check_keys(config: Config, data: dict[str, Any], allowed: set[str], prefix: str) -> None:
    for key in data:
        if key not in allowed:
            raise ConfigError(f"{config.where(prefix + key)}: unknown key (allowed: {', '.join(sorted(allowed))})")


def _string_list(config: Config, value: Any, key: str) -> list[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ConfigError(f"{config.where(key)} must be a list of strings")
    return list(value)
