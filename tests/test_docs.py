"""The documentation holds together: every relative link in README.md and docs/*.md points to a
file that exists and every anchor to a heading, no control character hides in the text, the
start-up figures are the benchmark's output, and the README stays a guide (under 200 lines)."""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
README_MAX_LINES = 200

#: ``[text](target)`` and ``![alt](target)``; the target ends at the first space (a title may
#: follow) or the closing parenthesis.
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+[^)]*)?\)")
#: fenced code blocks and inline code spans: what looks like a link there is code, not a link
FENCE = re.compile(r"^(```|~~~).*?^\1[^\n]*$", re.S | re.M)
CODE_SPAN = re.compile(r"`[^`\n]*`")
EXTERNAL = re.compile(r"^(?:[a-z][a-z0-9+.-]*:|//)", re.I)  # http:, https:, mailto:, ... and //host


def relative_links(text: str) -> list:
    """The relative link targets of a Markdown text, without their ``#anchor``; external links
    (any URL scheme), pure anchors and links inside code are left out."""
    text = CODE_SPAN.sub("", FENCE.sub("", text))
    out = []
    for target in LINK.findall(text):
        if EXTERNAL.match(target) or target.startswith("#"):
            continue
        out.append(target.split("#", 1)[0])
    return out


def broken_links(text: str, base: Path) -> list:
    """Relative link targets in ``text`` that do not resolve to an existing file or directory,
    resolved against ``base`` (the directory of the file holding the links)."""
    return [t for t in relative_links(text) if not (base / t).exists()]


@pytest.mark.parametrize("path", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_points_to_an_existing_file(path):
    assert broken_links(path.read_text(encoding="utf-8"), path.parent) == []


def control_characters(text: str) -> list:
    """(line, character code) of every control character but the newline: what a Python string
    without its r prefix leaves of a LaTeX command such as \\tfrac (a tab) or \\big (a backspace)."""
    return [(i, hex(ord(c))) for i, line in enumerate(text.split("\n"), 1) for c in line if ord(c) < 32]


@pytest.mark.parametrize("path", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_the_docs_hold_no_control_characters(path):
    assert control_characters(path.read_text(encoding="utf-8")) == []


def test_control_characters_are_found():
    """Negative control: a tab where a LaTeX tfrac was meant is found; an escaped backslash is not."""
    assert control_characters("$x = \tfrac12$\nfine\n\\big(") == [(1, "0x9")]


def test_the_docs_are_there_and_link_somewhere():
    """The pages this test walks exist and carry links, so the test above is not vacuous."""
    names = {p.name for p in DOCS}
    assert {"README.md", "physics.md", "integrator.md", "environment.md", "performance.md", "benchmarks.md",
            "recording.md", "agents.md", "testing.md"} <= names
    assert len(relative_links((ROOT / "README.md").read_text(encoding="utf-8"))) >= 10


def test_link_checker_reports_a_broken_link():
    """Negative control: a made-up target is reported, with its anchor stripped; existing targets,
    anchors, external links and code are not."""
    text = ("See [the physics](docs/physics.md#conventions), ![a frame](docs/img/env_frame.png),\n"
            "[gone](docs/no_such_page.md#somewhere) and ![gone too](img/missing.png \"title\").\n"
            "[web](https://example.org/x.md) [mail](mailto:a@b.c) [here](#layout)\n"
            "`[code](not_a_link.md)`\n```\n[fenced](also_not_a_link.md)\n```\n")
    assert broken_links(text, ROOT) == ["docs/no_such_page.md", "img/missing.png"]
    # relative to the file holding the link: docs/ pages link to img/..., not docs/img/...
    assert broken_links("![frame](img/env_frame.png)", ROOT / "docs") == []
    assert broken_links("![frame](img/env_frame.png)", ROOT) == ["img/env_frame.png"]


def test_readme_is_a_guide_under_200_lines():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").count("\n")
    assert lines < README_MAX_LINES, f"README.md has {lines} lines; move depth into docs/"


def cold_start_figures(path=ROOT / "docs" / "img" / "cold_start.json") -> dict:
    """(case, cache) -> the first step's seconds, from benchmarks.cold_start's output file."""
    import json

    runs = json.loads(path.read_text(encoding="utf-8"))["runs"]
    return {(run["case"], run["cache"]): run["first_step_s"] for run in runs}


def cold_start_misquotes(readme: str, performance: str, figures: dict) -> list:
    """The cold-start figures the README and docs/performance.md should quote (one decimal) and
    do not."""
    f = {key: f"{value:.1f}" for key, value in figures.items()}
    wanted = [(readme, f"{f['env', 'cold']} s / {f['env', 'warm']} s (8-env vector env: "
                       f"{f['vector env (8)', 'cold']} s / {f['vector env (8)', 'warm']} s)")]
    for case, row in (("simulator", "`Simulator(\"paper_example\").step(1)`"),
                      ("env", "`gym.make(\"ElasticStringPendulum-v0\")`, reset, step"),
                      ("vector env (8)", "`gym.make_vec(..., num_envs=8)`, reset, step")):
        wanted.append((performance, f"| {row} | {f[case, 'cold']} | {f[case, 'warm']} |"))
    return [text for doc, text in wanted if text not in doc]


def test_the_cold_start_figures_are_the_benchmarks_output():
    """The README's and docs/performance.md's start-up figures are docs/img/cold_start.json's
    (``python -m benchmarks.cold_start --repeats 1 --out docs/img``), and the compile notices
    announce at least the measured cold first step, and at most 30 % more."""
    from esp_gym.kernels.env_step import COLD_BATCH_STEP_S, COLD_ENV_STEP_S
    from esp_gym.kernels.specialise import COLD_SIMULATOR_STEP_S

    figures = cold_start_figures()
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    performance = (ROOT / "docs" / "performance.md").read_text(encoding="utf-8")
    assert cold_start_misquotes(readme, performance, figures) == []
    for announced, case in ((COLD_SIMULATOR_STEP_S, "simulator"), (COLD_ENV_STEP_S, "env"),
                            (COLD_BATCH_STEP_S, "vector env (8)")):
        assert figures[case, "cold"] <= announced <= 1.3 * figures[case, "cold"], (case, announced)


def test_a_misquoted_cold_start_figure_is_found():
    """Negative control: the output file's figures one tenth of a second off are misquotes."""
    figures = {key: value + 0.1 for key, value in cold_start_figures().items()}
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    performance = (ROOT / "docs" / "performance.md").read_text(encoding="utf-8")
    assert len(cold_start_misquotes(readme, performance, figures)) == 4


def heading_anchors(text: str) -> set:
    """The anchors GitHub gives the Markdown headings of ``text``: lower case, punctuation but
    hyphens and underscores dropped, spaces to hyphens; a repeated heading gets -1, -2, ..."""
    anchors, seen = set(), {}
    for line in FENCE.sub("", text).splitlines():
        match = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not match:
            continue
        slug = re.sub(r"[^\w\- ]", "", match.group(1).lower().replace("`", "")).replace(" ", "-")
        count = seen.get(slug, 0)
        seen[slug] = count + 1
        anchors.add(slug if count == 0 else f"{slug}-{count}")
    return anchors


def broken_anchors(text: str, base: Path, here: Path) -> list:
    """``target#anchor`` links of ``text`` (a file in ``base``; ``here`` the file itself, for
    pure ``#anchor`` links) whose Markdown target has no heading with that anchor."""
    text = CODE_SPAN.sub("", FENCE.sub("", text))
    out = []
    for target in LINK.findall(text):
        if EXTERNAL.match(target) or "#" not in target:
            continue
        path, anchor = target.split("#", 1)
        file = here if not path else base / path
        if file.suffix == ".md" and file.exists() and anchor not in heading_anchors(file.read_text(encoding="utf-8")):
            out.append(target)
    return out


@pytest.mark.parametrize("path", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_anchor_names_a_heading(path):
    assert broken_anchors(path.read_text(encoding="utf-8"), path.parent, path) == []


def test_the_anchor_checker_finds_a_missing_heading(tmp_path):
    """Negative control: a heading's anchor, with code, punctuation and a repeat, is found; a
    made-up one and one whose heading was renamed are reported."""
    text = "# The `winch`: reels, too\n## Cost\n## Cost\n[a](#the-winch-reels-too) [b](#cost-1) [c](#nowhere)\n"
    assert heading_anchors(text) == {"the-winch-reels-too", "cost", "cost-1"}
    page = tmp_path / "page.md"
    page.write_text(text, encoding="utf-8")
    assert broken_anchors(text, tmp_path, page) == ["#nowhere"]
    assert broken_anchors("[x](docs/agents.md#baselines-against-trained-policies-issue-15)", ROOT, page) == [
        "docs/agents.md#baselines-against-trained-policies-issue-15"]
