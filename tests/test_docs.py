"""The documentation holds together: every relative link in README.md and docs/*.md points to a
file that exists and every anchor to a heading, no control character hides in the text, the
quoted figures are their benchmarks' output files (benchmarks/quote.py), and the README stays a guide (under 200 lines)."""
import json
import re
from pathlib import Path

import pytest

from benchmarks import quote

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
    runs = json.loads(path.read_text(encoding="utf-8"))["runs"]
    return {(run["case"], run["cache"]): run["first_step_s"] for run in runs}


def test_the_compile_notices_announce_the_measured_cold_start():
    """The compile notices announce at least the cold first step of docs/img/cold_start.json
    (``python -m benchmarks.cold_start --out docs/img``), and at most 30 % more."""
    from esp_gym.kernels.drone.env import COLD_DRONE_BATCH_STEP_S, COLD_DRONE_ENV_STEP_S
    from esp_gym.kernels.env.step import COLD_BATCH_STEP_S, COLD_ENV_STEP_S
    from esp_gym.kernels.step.specialise import COLD_SIMULATOR_STEP_S

    figures = cold_start_figures()
    for announced, case in ((COLD_SIMULATOR_STEP_S, "simulator"), (COLD_ENV_STEP_S, "env"),
                            (COLD_BATCH_STEP_S, "vector env (8)"), (COLD_DRONE_ENV_STEP_S, "drone env"),
                            (COLD_DRONE_BATCH_STEP_S, "drone vector env (8)")):
        assert figures[case, "cold"] <= announced <= 1.3 * figures[case, "cold"], (case, announced)


@pytest.mark.parametrize("path", [p.relative_to(ROOT).as_posix() for p in quote.documents()])
def test_every_quoted_figure_is_its_output_files(path):
    """Every figure quoted between ``<!-- quote NAME -->`` and ``<!-- /quote -->`` is its
    benchmark's output file rendered (benchmarks/quote.py; ``python -m benchmarks.quote --write``
    after a rerun)."""
    text = (ROOT / path).read_text(encoding="utf-8")
    stale = quote.stale_quotes(text)
    assert stale == [], "\n".join(f"{name}: quoted {old!r}, the file says {new!r} ({quote.QUOTES[name].command})"
                                  for name, old, new in stale)


def test_the_headline_figures_are_quoted():
    """The README's figures and the performance page's tables are quotes, each at least once."""
    text = "".join(p.read_text(encoding="utf-8") for p in quote.documents())
    quoted = {m.group(1) for m in quote.QUOTE.finditer(text)}
    assert set(quote.QUOTES) - quoted == set()


def test_a_misquoted_figure_is_found():
    """Negative controls: output files a tenth off make their quotes stale, and an unknown quote
    name is an error that names it."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    performance = (ROOT / "docs" / "performance.md").read_text(encoding="utf-8")
    source = quote.QUOTES["cold_start.readme"].source
    data = json.loads((ROOT / source).read_text(encoding="utf-8"))
    for run in data["runs"]:
        run["first_step_s"] += 0.1
    assert [name for name, _, _ in quote.stale_quotes(readme, data={source: data})] == ["cold_start.env",
                                                                                    "cold_start.readme"]
    assert [name for name, _, _ in quote.stale_quotes(performance, data={source: data})] == ["cold_start.table"]
    with pytest.raises(KeyError, match="no_such.figure"):
        quote.stale_quotes("<!-- quote no_such.figure -->1<!-- /quote -->")


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
