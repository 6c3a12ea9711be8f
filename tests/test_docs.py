"""docs/ is part of the code: the generated pages match what the code says and nothing in the
repository points at documents outside it (the import rules of docs/architecture.md are
checked by tests/test_imports.py)."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from viewer.commands import docgen
ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"


# ----------------------------------------------------------------------------- generated pages

def test_generated_docs_are_up_to_date(tmp_path):
    """Regenerate scene-format.md and brdfs.md and compare with the committed files."""
    assert docgen.main(["--out", str(tmp_path)]) == 0
    for name in docgen.GENERATED:
        fresh = (tmp_path / name).read_text(encoding="utf-8")
        committed = (DOCS / name).read_text(encoding="utf-8") if (DOCS / name).is_file() else ""
        assert committed == fresh, f"docs/{name} is out of date: run python -m viewer.commands.docgen"


def test_every_scene_key_is_documented():
    assert docgen.check_fields_cover_the_code() == []


def test_the_key_check_can_fail(monkeypatch):
    """Leaving out a render key and a shared material sub-key is reported, naming each."""
    kept = tuple(f for f in docgen.SCENE_FIELDS if f.key not in ("raytrace_depth", "thin_film.ior"))
    monkeypatch.setattr(docgen, "SCENE_FIELDS", kept)
    problems = docgen.check_fields_cover_the_code()
    assert len(problems) == 2
    assert problems[0].startswith("render.raytrace_depth: accepted by viewer/scene/parse.py")
    assert problems[1].startswith("materials.NAME.thin_film.ior: accepted by viewer/scene/parse.py")


def test_shared_material_keys_are_the_registrys():
    shared = docgen.shared_material_params()
    assert {"spectral", "thin_film"} <= set(shared)
    assert set(shared["thin_film"]) == {"microfacet", "mirror", "dielectric"}


@pytest.mark.parametrize("f", docgen.SCENE_FIELDS, ids=lambda f: f"{f.section}.{f.key}")
def test_documented_default_is_what_the_validator_fills_in(f):
    """Writing the documented default explicitly gives the same scene as leaving the key out,
    and the documented bad value is refused with a message naming the key."""
    dv = docgen.default_value(f)
    assert docgen.allowed_text(f)  # raises when the bad value is accepted or the key is not named
    if dv is docgen.REQUIRED or dv is None:
        return
    value = dv.tolist() if isinstance(dv, np.ndarray) else dv
    explicit = docgen.parse_probe(docgen.probe_data(f, value))
    absent = docgen.parse_probe(docgen.probe_data(f, remove=True))
    assert explicit == absent


def test_generated_docs_name_every_model_and_key():
    from viewer import brdf

    text = (DOCS / "brdfs.md").read_text(encoding="utf-8")
    for name in brdf.names():
        assert f"## `{name}`" in text
        for p in brdf.get(name).spec.params:
            assert f"`{p.name}`" in text
    scene = (DOCS / "scene-format.md").read_text(encoding="utf-8")
    for f in docgen.SCENE_FIELDS:
        assert f"| `{f.key}` |" in scene


def test_handwritten_docs_exist_and_link_to_each_other():
    for name in ("conventions.md", "architecture.md", "python-api.md", "scene-format.md", "brdfs.md"):
        assert (DOCS / name).is_file(), f"docs/{name} missing"
    for page in DOCS.glob("*.md"):
        for target in re.findall(r"\]\(([^)#:]+\.md)", page.read_text(encoding="utf-8")):
            assert (page.parent / target).is_file(), f"{page.name} links to missing {target}"


# ----------------------------------------------------------------------------- self-contained

# References to documents outside the repository: planning documents, a sibling folder, and issue or
# work-item numbers (the pieces are joined so that this file does not match itself).
OUTSIDE_REFERENCE = re.compile("|".join((
    "CON" + "TRACT",
    "DES" + r"IGN\.md",
    r"\.\./sha" + "red",
    r"[Ii]ss" + r"ue [0-9]",
    r"[Ii]ss" + r"ue [\"'\u201c][A-Z]",   # a work item named by its title in quotes
    "Harden" + r"ing\"? [0-9]",          # ... or by its title and number
    "#" + r"[0-9]{2}\b",
)))


def outside_references(root: Path, files) -> list[str]:
    """'file:line: text' for every line of ``files`` (paths relative to ``root``) that points
    outside the repository."""
    bad = []
    for rel in files:
        try:
            text = (root / rel).read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue  # binary files (PNG, PLY, .npy) hold no prose
        for n, line in enumerate(text.splitlines(), 1):
            if OUTSIDE_REFERENCE.search(line):
                bad.append(f"{rel}:{n}: {line.strip()[:100]}")
    return bad


def test_nothing_points_outside_the_repository():
    try:
        out = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                             capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout (e.g. an unpacked sdist)")
    files = [f for f in out.splitlines() if f and (ROOT / f).is_file()]
    assert len(files) > 100
    assert outside_references(ROOT, files) == []


def test_the_outside_reference_check_can_fail(tmp_path):
    lines = ["fine", "see " + "CON" + "TRACT section 1", "as in " + "DES" + "IGN.md", "../sha" + "red/x",
             "fixed in " + "iss" + "ue 7", "PR " + "#" + "12", "colour #fff and 3 # 4",
             "atomic (" + "iss" + 'ue "Harden' + 'ing" 4)', "as " + "Harden" + "ing 3 asks", "an issue about x"]
    (tmp_path / "a.py").write_text("\n".join(lines))
    assert [b.split(":")[1] for b in outside_references(tmp_path, ["a.py"])] == ["2", "3", "4", "5", "6", "8", "9"]
