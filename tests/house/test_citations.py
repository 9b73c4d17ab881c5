"""Citations resolve for a reader of the project alone: every "model §N"
and every "[n]" cited in the sources, catalogs and exported headers names a section or a
reference of the README's model, and nothing cites files the project does not ship."""

from __future__ import annotations

import re

import numpy as np
from support.places import REPO

from ftsweep.kinds.table.header import COMPENSATION_CITED, render_header

SOURCES = [
    p
    for folder in ("pipeline", "stages", "catalogs")
    for p in sorted((REPO / folder).rglob("*"))
    if p.suffix in (".py", ".yaml")
]
README = (REPO / "README.md").read_text(encoding="utf-8")


def model_sections() -> set[int]:
    return {int(n) for n in re.findall(r"^### §(\d+) ", README, flags=re.M)}


def references() -> set[int]:
    block = README.split("### References", 1)[1].split("\n### ", 1)[0]
    return {int(n) for n in re.findall(r"^(\d+)\. ", block, flags=re.M)}


def test_the_readme_has_the_model_and_its_references():
    assert model_sections() >= set(range(1, 9))
    assert references() == {1, 2, 3, 4, 5, 6}
    for eq in range(1, 7):
        assert re.search(rf"^    \({eq}\) ", README, flags=re.M), f"equation ({eq}) is missing"


def test_every_citation_in_the_sources_resolves():
    sections, refs = model_sections(), references()
    cited = 0
    for path in SOURCES:
        text = path.read_text(encoding="utf-8")
        assert "physics.md" not in text and "shared/" not in text, f"{path} cites an unshipped file"
        assert not re.search(r"\bseed 00\d", text), f"{path} cites a seed by its internal number"
        for n in re.findall(r"model §(\d+)", text):
            assert int(n) in sections, f"{path}: model §{n} is not a section of the README"
            cited += 1
        # a citation is "[n]" after "of", "(" or a space; code indexes follow a name
        for n in re.findall(r"(?:of |\(| )\[(\d)\](?=[,):.]| [a-z])", text):
            assert int(n) in refs, f"{path}: [{n}] is not a reference of the README"
    assert cited > 30  # the docstrings do cite the model


def test_exported_headers_cite_the_readme_in_ascii():
    meta = {
        "layout": "ring",
        "generator": "ftsweep test",
        "created": "now",
        "pitch": (2.0, 1.0),
        "origin": (0.0, 0.0),
        "unit_nm": 1.0,
        "surface": "sinewave2d",
        "feed_um": 1.0,
        "nose_radius_um": 83.0,
        "spindle_rpm": 50.0,
        "pv_nm": 12.5,
        "sidecar_sha256": "0" * 64,
    }
    for method, phrase in COMPENSATION_CITED.items():
        text, _ = render_header("t", {**meta, "compensation": method}, np.zeros((2, 3), np.int64), "int32")
        assert text.isascii()
        assert phrase in text and "ftsweep README, 'The model'" in text
        for sec in re.findall(r"section (\d)", text):
            assert int(sec) in model_sections()


def test_every_document_the_code_cites_is_in_the_repository():
    # a docstring's "docs/architecture.md" or "README" must lead a reader to a file that exists
    cited = set()
    for path in [*SOURCES, REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        for name in re.findall(r"(?<![\w/.])((?:docs/)?[A-Za-z_-]+\.md)\b", path.read_text(encoding="utf-8")):
            cited.add(name)
            # a bare name is one in the repository's root or in docs/ (as the README's layout lists it)
            found = (REPO / name).is_file() or (REPO / "docs" / name).is_file()
            assert found, f"{path.name} cites {name}, which the repository does not hold"
    assert {"docs/architecture.md", "docs/performance.md", "docs/kinds.md"} <= cited


def test_the_command_reference_is_the_commands_own_help():
    """docs/reference.md is what the commands print for --help (regenerate it with
    `python -m ftsweep.cli.reference > docs/reference.md` after changing an option)."""
    import os
    import subprocess
    import sys

    # a fresh interpreter: a kind another test registered in this one would add its options
    env = {k: v for k, v in os.environ.items() if not k.startswith("FTSWEEP_")}
    rendered = subprocess.run(
        [sys.executable, "-m", "ftsweep.cli.reference"], capture_output=True, text=True, env=env, check=True
    ).stdout
    page = (REPO / "docs" / "reference.md").read_text(encoding="utf-8")
    stale = "docs/reference.md is stale: python -m ftsweep.cli.reference > docs/reference.md"
    assert page == rendered, stale


def _slug(heading: str) -> str:
    """A heading's anchor as GitHub makes it: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_every_link_into_the_guide_and_the_reference_lands_on_a_heading():
    pages = {
        name: (REPO / name).read_text(encoding="utf-8") for name in ("docs/guide.md", "docs/reference.md")
    }
    anchors = {
        name: {_slug(h) for h in re.findall(r"^#{1,4} (.+)$", text, flags=re.M)}
        for name, text in pages.items()
    }
    links = [(name, a) for name, a in re.findall(r"\]\((docs/\w+\.md)#([\w-]+)\)", README)]
    links += [(name, a) for name, text in pages.items() for a in re.findall(r"\]\(#([\w-]+)\)", text)]
    assert len(links) > 20, links
    missing = [f"{name}#{a}" for name, a in links if a not in anchors[name]]
    assert not missing, missing
