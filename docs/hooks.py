"""MkDocs hooks: the pages generated from the package at build time.

* ``index.md``: the README, its links pointing into the site;
* ``environments/<id>.md`` for every registered id and ``environments/parallel.md`` for
  the PettingZoo environment: the environment class's docstring (its manual: spaces,
  reward, episode end, arguments, version history) below a picture and the facts of the
  registration;
* ``scenarios.md``: every packaged scenario's header comment and description, with its
  picture; ``scenario-files.md``: the scenario file format (``envs/README.md``);
* ``models/<name>.md``: every shipped model's card (``srpb_gym/models/<name>/card.md``)
  with its video and learning curves.

Sphinx roles in docstrings (``:class:`~srpb_gym.env.SRPBNavEnv```) become code spans, in
the generated pages and in the API reference. The pictures are committed
(``python scripts/render_env_figures.py``), so the build needs no simulation.
"""

from __future__ import annotations

import inspect
import json
import re
import sys
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # the package of this checkout, installed or not
    sys.path.insert(0, str(ROOT))

import gymnasium as gym  # noqa: E402
import yaml  # noqa: E402

import srpb_gym  # noqa: E402, F401 - registers the ids
from srpb_gym.registration import MIX_ID, SCENARIO_IDS  # noqa: E402

ROLE = re.compile(r":(?:class|func|meth|mod|data|attr|exc|obj):`(~?)([\w.]+)`")
ROLE_HTML = re.compile(r":(?:class|func|meth|mod|data|attr|exc|obj):<code>(~?)([\w.]+)</code>")
MODELS = ROOT / "srpb_gym" / "models"
PARALLEL_PICTURE = "srpb_v0-parallel"


def _role_name(tilde: str, dotted: str) -> str:
    return dotted.rsplit(".", 1)[-1] if tilde else dotted


def plain_roles(text: str) -> str:
    """Sphinx cross-reference roles as Markdown code spans."""
    return ROLE.sub(lambda m: f"`{_role_name(m.group(1), m.group(2))}`", text)


def docstring_body(obj: Any) -> tuple[str, str]:
    """(summary line, the rest) of ``obj``'s docstring, as Markdown."""
    doc = inspect.cleandoc(obj.__doc__ or "")
    summary, _, rest = doc.partition("\n")
    return plain_roles(summary.strip()), plain_roles(rest.strip())


def scenario_data(name: str) -> tuple[str, dict[str, Any]]:
    """(header comment as Markdown paragraphs, parsed YAML) of a packaged scenario."""
    text = (ROOT / "envs" / f"{name}.yaml").read_text(encoding="utf-8")
    header: list[str] = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        line = line[1:].strip()
        if line.startswith(("Tests:", "What it tests:", "Metrics it moves:")) and header:
            header.append("")
        header.append(line)
    return "\n".join(header), yaml.safe_load(text)


def _facts(rows: list[tuple[str, str]]) -> str:
    lines = ["| property | value |", "| --- | --- |"]
    lines += [f"| {key} | {value} |" for key, value in rows]
    return "\n".join(lines)


def env_page(env_id: str) -> str:
    """The page of a registered Gymnasium id."""
    spec = gym.spec(env_id)
    module, _, name = spec.entry_point.partition(":")
    cls = getattr(__import__(module, fromlist=[name]), name)
    summary, body = docstring_body(cls)
    rows = [("make", f'`gym.make("{env_id}")`'), ("entry point", f"`{spec.entry_point}`"),
            ("step limit", f"`max_episode_steps={spec.max_episode_steps}`"),
            ("API", f"[`{name}`](../api.md#{module}.{name})")]  # fmt: skip
    intro = ""
    scenario = spec.kwargs.get("scenario")
    if scenario:
        header, data = scenario_data(scenario)
        rows.insert(1, ("scenario", f"[`{scenario}`](../scenarios.md#{scenario}) "
                                    f"(`envs/{scenario}.yaml`)"))  # fmt: skip
        rows.append(("time limit", f"{data.get('time_limit', 60.0):g} s"))
        rows.append(("robots (multi-robot)", f"up to {len(data.get('robots') or [1])}"))
        intro = f"{' '.join(str(data.get('description', '')).split())}\n\n{header}\n"
    else:
        names = ", ".join(f"[`{s}`](../scenarios.md#{s})" for s in SCENARIO_IDS.values())
        rows.insert(1, ("scenarios", f"{names}, one drawn per `reset`"))
    return (f"# {env_id}\n\n![{env_id}](../figures/envs/{env_id}.png)\n\n{summary}\n\n"
            f"{_facts(rows)}\n\n{intro}\n{body}\n")  # fmt: skip


def parallel_page() -> str:
    """The page of the PettingZoo environment."""
    from srpb_gym.pettingzoo_env import SRPBParallelEnv

    summary, body = docstring_body(SRPBParallelEnv)
    rows = [("make", '`srpb_gym.parallel_env(scenario="crowd", n_robots=3)`'),
            ("AEC version", '`srpb_gym.aec_env(scenario="crowd", n_robots=3)`'),
            ("class", "[`srpb_gym.pettingzoo_env.SRPBParallelEnv`]"
                      "(../api.md#srpb_gym.pettingzoo_env.SRPBParallelEnv)"),
            ("name", f"`{SRPBParallelEnv.metadata['name']}`")]  # fmt: skip
    return (f"# PettingZoo parallel environment\n\n"
            f"![three robots in crowd](../figures/envs/{PARALLEL_PICTURE}.png)\n\n"
            f"{summary}\n\n{_facts(rows)}\n\nSee [Multi-robot](../multi-robot.md) for an "
            f"example, training and evaluation.\n\n{body}\n")  # fmt: skip


def scenarios_page() -> str:
    """Every packaged scenario: header, description, facts and picture."""
    parts = ["# Scenarios", "",
             "The packaged scenarios are the YAML files of `envs/`; each file's header says "
             "what it tests and which metrics it moves. The format of a scenario file, to "
             "write your own (`gym.make(\"SRPB-Custom-v0\", scenario=\"my_lab.yaml\")`), "
             "is in [Scenario files](scenario-files.md).", ""]  # fmt: skip
    for env_id, name in SCENARIO_IDS.items():
        header, data = scenario_data(name)
        description = " ".join(str(data.get("description", "")).split())
        parts += [f"## {name}", "", f"![{name}](figures/envs/{env_id}.png)", "",
                  f"[`{env_id}`](environments/{env_id}.md), `envs/{name}.yaml`: "
                  f"{description} Time limit {data.get('time_limit', 60.0):g} s; places for "
                  f"{len(data.get('robots') or [1])} robots.", "", header, ""]  # fmt: skip
    return "\n".join(parts)


def scenario_files_page() -> str:
    """``envs/README.md``, the scenario file format."""
    return (ROOT / "envs" / "README.md").read_text(encoding="utf-8")


def model_names() -> list[str]:
    """The shipped models, by name."""
    return sorted(p.parent.name for p in MODELS.glob("*/card.md"))


def model_page(name: str) -> str:
    """A shipped model's card, its video and its learning curves."""
    card = (MODELS / name / "card.md").read_text(encoding="utf-8")
    facts = json.loads((MODELS / name / "card.json").read_text(encoding="utf-8"))
    env_id = facts["env"]
    scenario = "mix" if env_id == MIX_ID else SCENARIO_IDS.get(env_id, "")
    extra = []
    if (ROOT / "docs" / "videos" / f"{name}.gif").exists():
        where = " (in `doorway`)" if scenario == "mix" else ""
        extra += ["## One test episode", "", f"Seed 10000{where}:", "",
                  f"![{name}, seed 10000](../videos/{name}.gif)", ""]  # fmt: skip
    curves = ROOT / "docs" / "figures" / f"learning_{scenario}.png"
    if curves.exists() and "robots" not in facts:  # the single-robot models' curves
        extra += ["## Learning curves", "",
                  f"![learning curves, {scenario}](../figures/learning_{scenario}.png)",
                  ""]  # fmt: skip
    return card.rstrip() + "\n\n" + "\n".join(extra)


def home_page() -> str:
    """The README, with its links pointing into the site."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    text = text.replace("](envs/README.md)", "](scenario-files.md)")
    source = "Each id links to its source (a scenario file, a docstring); on the site, to its page."
    text = text.replace(source, "Each id links to its page.")
    for env_id, scenario in SCENARIO_IDS.items():
        text = text.replace(f"](envs/{scenario}.yaml)", f"](environments/{env_id}.md)")
    text = text.replace("](srpb_gym/mix.py)", f"](environments/{MIX_ID}.md)")
    text = text.replace("](srpb_gym/pettingzoo_env.py)", "](environments/parallel.md)")
    return text.replace("](docs/", "](").replace('src="docs/', 'src="')


def generated_pages() -> dict[str, str]:
    """Every generated page, by its path in the site's sources."""
    pages = {"index.md": home_page()}
    pages |= {f"environments/{env_id}.md": env_page(env_id)
             for env_id in (*SCENARIO_IDS, MIX_ID)}  # fmt: skip
    pages["environments/parallel.md"] = parallel_page()
    pages["scenarios.md"] = scenarios_page()
    pages["scenario-files.md"] = scenario_files_page()
    pages.update({f"models/{name}.md": model_page(name) for name in model_names()})
    return pages


def on_files(files: Files, config: Any) -> Files:
    """Add the generated pages."""
    for path, content in generated_pages().items():
        files.append(File.generated(config, path, content=content))
    return files


def on_page_content(html: str, page: Any, config: Any, files: Files) -> str:
    """Sphinx roles left in the API reference's docstrings become code."""
    return ROLE_HTML.sub(lambda m: f"<code>{_role_name(m.group(1), m.group(2))}</code>", html)


__all__ = ["generated_pages", "on_files", "on_page_content"]
