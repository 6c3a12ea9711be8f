"""Bounds on what the viewer reads, checked before a parser spends memory on it.

A small file can ask a parser for gigabytes: a TOML key of 25,000 dotted parts (the TOML reader's
bookkeeping grows with the square of a key's parts), a PNG text chunk that inflates to a scene
of that kind, a sparse mesh file of 2 GB (zeros on disk cost nothing, in a parser's memory they
do). Each check here looks at the file's size (a stat), its first bytes or its header, never at
the whole, and returns the problem in words (or None); the caller names the file.

The bounds (also in docs/scene-format.md):

* a TOML text (scene, material or state file, a screenshot's scene) holds at most
  ``MAX_TOML_BYTES`` bytes, and no key of more than ``MAX_KEY_PARTS`` dotted parts;
* a PNG text chunk inflates to at most ``MAX_PNG_TEXT`` bytes;
* a mesh file holds at most ``MAX_MESH_BYTES`` bytes; a text format (OBJ, OFF, glTF)
  has no NUL byte in its first ``HEAD_BYTES``; a PLY header declares at most
  ``MAX_MESH_ELEMENTS`` vertices and as many faces, no more than the file's bytes can hold.
"""

from __future__ import annotations

import os
import re

#: the most bytes of a TOML text (a scene of 100,000 objects is about 12 MB)
MAX_TOML_BYTES = 32 * 1024 * 1024
#: the most dotted parts of one TOML key (a scene's longest is 4: materials.NAME.coating.ior)
MAX_KEY_PARTS = 64
#: the most bytes a PNG text chunk inflates to (a screenshot's scene is a TOML text)
MAX_PNG_TEXT = MAX_TOML_BYTES
#: the most bytes of a mesh file
MAX_MESH_BYTES = 1024 * 1024 * 1024
#: the most vertices (and faces) a PLY header may declare: a scene's triangles at most
MAX_MESH_ELEMENTS = 30_000_000
#: the bytes of a file's start that are looked at
HEAD_BYTES = 64 * 1024

# strings and comments, left to right as TOML reads them (each replaced, its line breaks kept)
_STRINGS = re.compile(r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"[^"\\\n]*(?:\\.[^"\\\n]*)*"|\'[^\'\n]*\'|#[^\n]*')
# a stretch without = , brackets, braces or line breaks (a key, or a value) holding more dots
# than a key may have parts; it starts only after such a character, so each stretch is tried once
_DEEP = re.compile(r"(?:^|(?<=[=\n,\[\]{}]))(?:[^=\n,\[\]{}.]*\.){" + str(MAX_KEY_PARTS) + "}")


def _blank(m) -> str:
    return ("" if m.group(0).startswith("#") else "Q") + "\n" * m.group(0).count("\n")


def toml_problem(text: str) -> str | None:
    """Why the TOML ``text`` is not read (too long, a key of too many dotted parts), or None.
    Linear in the text's length: its strings and comments are blanked out first, then each
    stretch between ``= , [ ] { }`` and line breaks has its dots counted."""
    if len(text) > MAX_TOML_BYTES:
        return f"{len(text)} characters; a TOML text holds at most {MAX_TOML_BYTES}"
    if text.count(".") < MAX_KEY_PARTS:
        return None
    code = _STRINGS.sub(_blank, text)
    m = _DEEP.search(code)
    if m is not None:
        line = code.count("\n", 0, m.start()) + 1
        return f"line {line}: a key of more than {MAX_KEY_PARTS} dotted parts; at most {MAX_KEY_PARTS}"
    return None


def file_size_problem(size: int, limit: int, what: str) -> str | None:
    if size > limit:
        return f"{size} bytes; a {what} holds at most {limit}"
    return None


def _head(path, n: int = HEAD_BYTES) -> bytes:
    with open(path, "rb") as f:
        return f.read(n)


_PLY_SIZES = {"char": 1, "int8": 1, "uchar": 1, "uint8": 1, "short": 2, "int16": 2, "ushort": 2, "uint16": 2,
              "int": 4, "int32": 4, "uint": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}


def ply_problem(head: bytes, size: int) -> str | None:
    """Why a PLY file of ``size`` bytes starting with ``head`` is not read (its header declares
    more elements than allowed or than the file can hold), or None. A header that does not
    parse is left to the reader (its own message)."""
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        return None
    lines = head[:end].decode("latin-1").splitlines()
    fmt = next((l.split()[1] for l in lines if l.startswith("format ") and len(l.split()) > 1), "ascii")
    current = None
    rows: dict[str, list[int]] = {}  # element: [count, bytes of a binary row, numbers of a text row]
    for line in lines:
        t = line.split()
        if len(t) >= 3 and t[0] == "element":
            try:
                count = int(t[2])
            except ValueError:
                return None
            if count < 0:
                return f"its header declares {count} {t[1]} elements"
            if t[1] in ("vertex", "face") and count > MAX_MESH_ELEMENTS:
                return f"its header declares {count} {t[1]} elements; at most {MAX_MESH_ELEMENTS}"
            current = t[1]
            rows[current] = [count, 0, 0]
        elif len(t) >= 3 and t[0] == "property" and current is not None:
            row = rows[current]
            if t[1] == "list" and len(t) >= 5:
                # its count, and (for faces) at least three indices
                n = 3 if current == "face" else 0
                row[1] += _PLY_SIZES.get(t[2], 1) + n * _PLY_SIZES.get(t[3], 1)
                row[2] += 1 + n
            else:
                row[1] += _PLY_SIZES.get(t[1], 1)
                row[2] += 1
    binary = fmt.startswith("binary")
    # a text row: each number at least one digit and a separator
    need = sum(count * (b if binary else 2 * n) for count, b, n in rows.values())
    if need > size:
        return f"its header declares elements of at least {need} bytes; the file has {size}"
    return None


TEXT_MESHES = (".obj", ".off", ".gltf")


def mesh_problem(path, size: int) -> str | None:
    """Why the mesh file ``path`` of ``size`` bytes is not read, or None (see the module's doc)."""
    problem = file_size_problem(size, MAX_MESH_BYTES, "mesh file")
    if problem:
        return problem
    ext = os.path.splitext(str(path))[1].lower()
    if ext not in TEXT_MESHES + (".ply",):  # STL and GLB: binary, their counts checked by the reader
        return None
    try:
        head = _head(path)
    except OSError:
        return None  # the reader names it
    if ext == ".ply":
        return ply_problem(head, size)
    nul = head.find(b"\0")
    if nul >= 0:
        return f"a NUL byte at byte {nul}: not a {ext[1:].upper()} text file"
    return None
