"""MkDocs hooks of the senbench site (mkdocs.yml names this file under ``hooks:``).

- ``<!-- include: PATH -->`` on a line of its own, in a page, is replaced by the text of
  PATH (relative to the repository root): REPRODUCTION.md, the suite files, the example
  packages' sources. The page shows the file as it is in the repository, so the two cannot
  drift apart. A missing file fails the build.
- ``<!-- generated: builtin-plugins -->`` is replaced by tables of every built-in env,
  agent, encoder and sampler as the registry holds them: each config field's default, each
  agent's per-env defaults with their sources, each search range. They are read from the
  plugins at build time, so the page cannot fall behind the code.
- The figures under ``results/<suite>/`` (``curves.png``, ``traces.png``) are served at
  the same paths in the site, so REPRODUCTION.md's image links work unchanged and the
  pictures are not copied into ``docs/``.

Nothing here reaches the network.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File, Files

INCLUDE = re.compile(r"^<!-- include: (?P<path>[^ ]+) -->$", re.MULTILINE)
GENERATED = "<!-- generated: builtin-plugins -->"
FIGURES = ("curves.png", "traces.png")
BUILT_IN = "senbench"  # the distribution of the plugins shipped with senbench


def _root(config) -> Path:
    return Path(config.config_file_path).resolve().parent


def on_files(files: Files, config) -> Files:
    root = _root(config)
    for figure in sorted((root / "results").glob("*/*.png")):
        if figure.name in FIGURES:
            uri = figure.relative_to(root).as_posix()
            files.append(File.generated(config, uri, abs_src_path=str(figure)))
    return files


def on_page_markdown(markdown: str, page, config, files) -> str:
    root = _root(config)

    def include(match: re.Match) -> str:
        path = (root / match["path"]).resolve()
        if root not in path.parents or not path.is_file():
            raise PluginError(f"{page.file.src_uri}: cannot include {match['path']}: "
                              "no such file in the repository")
        return path.read_text(encoding="utf-8").rstrip("\n")

    markdown = INCLUDE.sub(include, markdown)
    if GENERATED in markdown:
        markdown = markdown.replace(GENERATED, builtin_plugins())
    return markdown


def _value(value) -> str:
    """A default as a suite would write it, in a code span."""
    if isinstance(value, type):
        value = value.__name__
    elif isinstance(value, tuple | frozenset | set):
        value = sorted(value) if isinstance(value, frozenset | set) else list(value)
    return "`" + repr(value).replace("|", "\\|") + "`"


def _config_defaults(config: type) -> dict[str, object]:
    defaults = {}
    for f in dataclasses.fields(config):
        if f.default is not dataclasses.MISSING:
            defaults[f.name] = f.default
        elif f.default_factory is not dataclasses.MISSING:
            defaults[f.name] = f.default_factory()
        else:
            defaults[f.name] = "required"
    return defaults


def _range(param) -> str:
    if param is None:
        return ""
    if hasattr(param, "values"):
        return "one of " + ", ".join(_value(v) for v in param.values)
    scale = ", log" if getattr(param, "log", False) else ""
    return f"[{param.low:g}, {param.high:g}{scale}]"


def _config_table(config: type, search_space, columns: dict[str, dict] | None = None) -> list[str]:
    """A row per config field: its default, any per-env override, its search range."""
    columns = columns or {}
    head = ["field", "default", *(f"`{key}`" for key in columns), "`senbench tune` range"]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for name, default in _config_defaults(config).items():
        overrides = [_value(values[name]) if name in values else "" for values in columns.values()]
        cells = [f"`{name}`", default if default == "required" else _value(default), *overrides,
                 _range(search_space.get(name))]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def builtin_plugins() -> str:
    """Markdown tables of what the built-in plugins register, read from the registry."""
    from senbench.plugin.manager import registries

    reg = registries()
    out: list[str] = []

    def built_in(registry):
        return [n for n in registry.names() if registry.origin(n).distribution == BUILT_IN]

    out += ["### Envs", "", "| env | actions | state (low … high) | threshold | episode steps | "
            "options |", "| --- | --- | --- | --- | --- | --- |"]
    for name in built_in(reg.envs):
        env = reg.envs.get(name)
        state = ", ".join(f"{label} ({low:g} … {high:g})" for label, low, high
                          in zip(env.state_labels, env.state_low, env.state_high, strict=True))
        options = ", ".join(f"`{k}`" for k in env.options) or "—"
        out.append(f"| `{name}` | {env.actions} | {state} | {env.threshold:g} "
                   f"({env.threshold_source}) | {env.max_episode_steps} | {options} |")
    out.append("")

    out += ["### Agents", ""]
    for name in built_in(reg.agents):
        agent = reg.agents.get(name)
        out += [f"#### `{name}`", "", agent.description + ".", "",
                f"Actions: {', '.join(sorted(agent.actions))}; observations: "
                f"{', '.join(sorted(agent.observations))}. Config: `{agent.config.__name__}`.", ""]
        columns = {key: dict(d.values) for key, d in agent.defaults.items()}
        out += _config_table(agent.config, agent.search_space, columns)
        if agent.defaults:
            out += ["", "Where the per-env defaults come from:", ""]
            out += [f"- `{key}`: {d.source}" for key, d in agent.defaults.items()]
        out.append("")

    out += ["### Encoders", ""]
    for name in built_in(reg.encoders):
        encoder = reg.encoders.get(name)
        out += [f"#### `{name}`", "", encoder.description + ".", "",
                f"Config: `{encoder.config.__name__}`; frozen into TorchScript for inference: "
                f"{'yes' if encoder.traceable else 'no'}.", ""]
        out += _config_table(encoder.config, encoder.search_space) + [""]

    out += ["### Samplers", ""]
    for name in built_in(reg.samplers):
        sampler = reg.samplers.get(name)
        out += [f"#### `{name}`", "", sampler.description + ".", "",
                f"Config: `{sampler.config.__name__}`; labelled frames: {sampler.labels}.", ""]
        out += _config_table(sampler.config, {}) + [""]
    return "\n".join(out)
