"""The documentation agrees with the code it describes."""

from pathlib import Path

from dem.io.scene import schema_markdown

DOCS = Path(__file__).resolve().parents[1] / "docs"


def test_scene_reference_matches_schema():
    page = (DOCS / "scene_reference.md").read_text()
    assert schema_markdown().strip() in page, (
        "docs/scene_reference.md is out of date: regenerate it from schema_markdown()")


def test_readme_quick_start_is_two_commands():
    readme = (DOCS.parent / "README.md").read_text()
    block = readme.split("## Quick start", 1)[1].split("```")[1].split("\n", 1)[1]
    assert [line for line in block.splitlines() if line.strip()] == ["make demo", "make test"]
