"""Rules the tests themselves obey (docs/architecture.md): they read public attributes only, so
a test never pins a private detail of the code it checks. Read from the sources (no import)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# An attribute whose name starts with one underscore, read from an object that is not ``self`` /
# ``cls`` (a harness class's own state); os's exit and namedtuple's replace / asdict / fields /
# make (underscored) are public by their library's convention.
PRIVATE_READ = re.compile(r"(?<![\w.])(?!self\.|cls\.)([A-Za-z_][\w]*(?:\([^()]*\))?(?:\.\w+)*)\._(?!_)(\w+)")
ALLOWED = {"exit", "replace", "asdict", "fields", "make"}   # the names after the underscore


def private_reads(root: Path, files) -> list[str]:
    """'file:line: text' for each read of a private attribute in ``files`` (relative to root)."""
    bad = []
    for rel in files:
        for n, line in enumerate((root / rel).read_text(encoding="utf-8").splitlines(), 1):
            code = re.sub(r"#.*", "", line)
            code = re.sub(r"\"[^\"]*\"|'[^']*'", '""', code)   # strings name things, they read nothing
            if any(m.group(2) not in ALLOWED for m in PRIVATE_READ.finditer(code)):
                bad.append(f"{rel}:{n}: {line.strip()[:100]}")
    return bad


def test_tests_read_public_attributes_only():
    files = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "tests").glob("*.py")
                   if p.name not in ("test_imports.py", "test_test_rules.py"))   # these quote offences
    assert len(files) > 50
    assert private_reads(ROOT, files) == []


def test_the_private_read_check_can_fail(tmp_path):
    # the offending lines are joined from pieces ("." + "_x"), so this file quotes no private read
    dot_ = "." + "_"
    lines = ["rv.spp + rv.key", f"rv{dot_}renderer.setup", f"app.session.mc{dot_}key = None",
             f"self{dot_}own = 1", "x.__class__", f"os{dot_}exit(0)", f"nt{dot_}replace(a=1)", f"f(r){dot_}pool",
             f"'a{dot_}b in a string'", f"ok  # a{dot_}comment"]
    (tmp_path / "t.py").write_text("\n".join(lines) + "\n")
    assert [b.split(":")[1] for b in private_reads(tmp_path, ["t.py"])] == ["2", "3", "8"]
