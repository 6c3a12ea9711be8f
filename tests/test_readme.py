"""The README's quick start is what CI runs: the test command in .ci/run appears verbatim in the
README, and the README documents every CLI command that exists."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    cmd = [l for l in ci if "pytest" in l and not l.startswith("#")]
    assert len(cmd) == 1
    readme = (ROOT / "README.md").read_text()
    assert cmd[0].strip() in readme


def test_readme_documents_each_command():
    from viewer.commands.cli import COMMANDS

    readme = (ROOT / "README.md").read_text()
    for c in COMMANDS:
        assert re.search(rf"### `brdf-viewer {c}`", readme), c


def test_readme_is_a_front_door_linking_every_page():
    """The README keeps the quick start, the commands and where to read more; detail lives in
    docs/, and every page there is reachable from it (and every link it has resolves)."""
    readme = (ROOT / "README.md").read_text()
    links = set(re.findall(r"\]\(([^)#:]+\.md)", readme))
    for target in links:
        assert (ROOT / target).is_file(), f"README links to missing {target}"
    for page in (ROOT / "docs").glob("*.md"):
        assert f"docs/{page.name}" in links, f"docs/{page.name} is not linked from the README"
    assert len(readme.splitlines()) < 250, "per-feature detail belongs in docs/"
