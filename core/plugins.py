"""The plugin manager: discovery, plugins.toml, the allow-list, and validation.

Modelled on pytest, datasette and llm. Plugins come from the ``frontal3d``
entry-point group (the built-in families use it too, so they are no special case)
and from module paths listed in plugins.toml. A plugin that fails to import is
reported by name and skipped, so one broken package never hides the others; a
hookimpl whose name matches no spec fails loudly through ``check_pending()``.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import os
import sys
import types
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pluggy

from frontal3d import hookspecs
from frontal3d.config import Config, coerce_setting, merge_family_settings
from frontal3d.errors import ConfigError, PluginError, UnknownFamilyError
from frontal3d.family import Family

#: Comma-separated plugin names to load; unset = all, empty = none but the core.
ALLOW_LIST_ENV = "FRONTAL3D_LOAD_PLUGINS"
ENTRY_POINT_GROUP = "frontal3d"
CORE_PLUGIN = "frontal3d.default_plugins"


@dataclass
class PluginInfo:
    """What ``frontal3d plugins`` shows about one plugin."""

    name: str
    source: str
    version: str | None = None
    hooks: list[str] = field(default_factory=list)
    error: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "version": self.version, "source": self.source, "hooks": self.hooks, "error": self.error}


class Plugins:
    """A loaded plugin manager plus the families it provides and their settings."""

    def __init__(self, config: Config | None = None):
        self.config = config or Config()
        self.pm = pluggy.PluginManager("frontal3d")
        self.pm.add_hookspecs(hookspecs)
        self.infos: list[PluginInfo] = []
        self._load()
        self.families = self._collect_families()

    @property
    def hook(self) -> Any:
        return self.pm.hook

    @property
    def broken(self) -> list[PluginInfo]:
        return [info for info in self.infos if info.error]

    def family(self, name: str) -> Family:
        """The family called ``name``, or an error listing the installed ones."""
        if name not in self.families:
            known = ", ".join(sorted(self.families)) or "none"
            raise UnknownFamilyError(f"unknown family {name!r} (installed: {known})")
        return self.families[name]

    def settings(self, family_name: str, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
        """The family's settings: core defaults < family defaults < plugins.toml < ``overrides``."""
        family = self.family(family_name)
        merged = merge_family_settings(self.config, family_name, family.settings)
        for key, value in (overrides or {}).items():
            if key not in merged:
                raise ConfigError(f"unknown setting {key!r} for family {family_name!r}")
            merged[key] = coerce_setting(value, merged[key], f"setting {key!r}", key)
        return merged

    def _load(self) -> None:
        allow = _allow_list()
        self._register(importlib.import_module(CORE_PLUGIN), PluginInfo(name="frontal3d", source="core"))
        entry_points = {ep.name: ep for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)}
        names = list(entry_points)
        if self.config.enabled is not None:
            unknown = [n for n in self.config.enabled if n not in entry_points]
            if unknown:
                raise ConfigError(f"{self.config.where('plugins.enabled')}: unknown plugin(s) {', '.join(unknown)} (installed: {', '.join(sorted(entry_points))})")
            names = list(self.config.enabled)
        for name in self.config.disabled:
            if name not in entry_points:
                raise ConfigError(f"{self.config.where('plugins.disabled')}: unknown plugin {name!r}")
        # pluggy calls the last registered first: register in reverse so the first listed wins.
        for name in reversed(names):
            if name in self.config.disabled or (allow is not None and name not in allow):
                continue
            ep = entry_points[name]
            version = ep.dist.version if ep.dist else None
            source = f"entry point ({ep.dist.name if ep.dist else '?'})"
            info = PluginInfo(name=name, source=source, version=version)
            try:
                module = ep.load()
            except Exception as exc:  # a broken plugin must not hide the others
                info.error = f"failed to import {ep.value}: {type(exc).__name__}: {exc}"
                self.infos.append(info)
                continue
            self._register(module, info)
        for path in self.config.modules:
            info = PluginInfo(name=path.stem, source=f"plugins.toml ({path})")
            if allow is not None and path.stem not in allow:
                continue
            try:
                module = _import_path(path)
            except Exception as exc:
                info.error = f"failed to import {path}: {type(exc).__name__}: {exc}"
                self.infos.append(info)
                continue
            self._register(module, info)
        try:
            self.pm.check_pending()
        except pluggy.PluginValidationError as exc:
            raise PluginError(f"plugin {_plugin_name(self.pm, exc.plugin)}: {exc}") from exc

    def _register(self, module: types.ModuleType, info: PluginInfo) -> None:
        try:
            self.pm.register(module, name=info.name)
        except (pluggy.PluginValidationError, ValueError) as exc:
            raise PluginError(f"plugin {info.name}: {exc}") from exc
        info.hooks = sorted({caller.name for caller in self.pm.get_hookcallers(module) or []})
        self.infos.append(info)

    def _collect_families(self) -> dict[str, Family]:
        families: dict[str, Family] = {}
        for impl in self.pm.hook.frontal3d_register_families.get_hookimpls():
            for family in impl.function() or []:
                if not isinstance(family, Family):
                    raise PluginError(f"plugin {impl.plugin_name}: frontal3d_register_families must return Family objects, got {type(family).__name__}")
                if family.name in families:
                    raise PluginError(f"family {family.name!r} is declared twice (again by plugin {impl.plugin_name})")
                families[family.name] = family
        return families


def _allow_list() -> set[str] | None:
    value = os.environ.get(ALLOW_LIST_ENV)
    if value is None:
        return None
    return {name.strip() for name in value.split(",") if name.strip()}


def _import_path(path: Path) -> types.ModuleType:
    if not path.is_file():
        raise FileNotFoundError(f"no such file: {path}")
    module_name = f"frontal3d_local_{path.stem}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot import {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    spec.loader.exec_module(module)
    return module


def _plugin_name(pm: pluggy.PluginManager, plugin: object) -> str:
    return pm.get_name(plugin) or getattr(plugin, "__name__", repr(plugin))
