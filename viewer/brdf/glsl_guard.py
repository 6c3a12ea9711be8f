"""What a ``.brdf`` file's GLSL may cost before the viewer compiles it (no GL here).

A file is code from anyone, and a shader that never ends or that is too large for the compiler
freezes whatever runs it (a window's frame, ``brdf-viewer check``), or on a real GPU resets the
driver. Three guards, from the cheapest on:

* sizes, checked before anything is parsed or compiled (``check_sizes``): the file's bytes, the
  bytes of its GLSL sections, its lines and the element count of an array whose size is a
  number. Each limit is far above what a BRDF needs (BRDF Explorer's 40 published files are
  at most a few kilobytes and 200 lines); a file over one is refused in one line naming it.
* loops (``check_loops`` and ``guard_loops``): a loop whose condition is missing or always true
  (``while (true)``, ``for (;;)``, ``do ... while (1)``) is refused with its line; every other
  loop runs under a budget: each of the file's ``while`` and ``for`` conditions first counts one
  step on a counter that the entry points (``BRDF``, ``sampleBRDF``) set to 0, and is false
  once ``MAX_LOOP_STEPS`` steps were counted in one call. So no call of the file's functions runs
  more than ``MAX_LOOP_STEPS`` loop steps in all, nested loops included, on any GPU; the GL side
  (``viewer.gl.file_brdf``) reads the counter after a call and refuses a file that reached it,
  so a loop of 1e9 steps is an error, not a silently shortened result.
* time and memory: the first compile and a 4 x 4 render of a file's program run in a child
  process with a time and a memory limit (``viewer.gl.file_probe``).
"""

from __future__ import annotations

import re

from viewer import ViewerError

#: bytes of a whole .brdf file
MAX_FILE_BYTES = 256 * 1024
#: bytes of the GLSL of its shader and isFunc sections together
MAX_GLSL_BYTES = 64 * 1024
#: lines of a file
MAX_LINES = 4000
#: elements of one array whose size is written as a number
MAX_ARRAY = 4096
#: loop steps (conditions tested) in one call of BRDF or sampleBRDF, all loops together; below
#: the 65,535 steps at which Mesa llvmpipe ends any loop by itself, so that the budget, not the
#: driver, ends a long loop there too (and reports it)
MAX_LOOP_STEPS = 16384

_LOOP = re.compile(r"\b(for|while)\s*\(")
_ARRAY = re.compile(r"\[\s*(\d+)[uU]?\s*\]")
_ALWAYS = re.compile(r"^\s*(?:true|[1-9]\d*|\(\s*true\s*\)|\(\s*[1-9]\d*\s*\))?\s*$")


def _kb(n: int) -> str:
    return f"{n // 1024} KB"


def check_file_size(name: str, size: int) -> None:
    """Refuse a file of ``size`` bytes over ``MAX_FILE_BYTES`` (before it is read)."""
    if size > MAX_FILE_BYTES:
        raise ViewerError(f"{name}: the file has {size:,} bytes; a .brdf file may have at most "
                          f"{_kb(MAX_FILE_BYTES)} ({MAX_FILE_BYTES:,} bytes)")


def check_sizes(name: str, text: str) -> None:
    """Refuse a file's ``text`` over the size limits (its bytes and its lines)."""
    check_file_size(name, len(text.encode("utf-8", errors="replace")))
    n = text.count("\n") + 1
    if n > MAX_LINES:
        raise ViewerError(f"{name}: the file has {n:,} lines; a .brdf file may have at most {MAX_LINES:,}")


def check_code(name: str, code_lines: dict[int, str]) -> None:
    """Refuse GLSL (``{line number: code}`` of the shader and isFunc sections, comments taken out)
    over ``MAX_GLSL_BYTES``, with an array over ``MAX_ARRAY`` elements or a loop that cannot end."""
    total = sum(len(c.encode("utf-8", errors="replace")) + 1 for c in code_lines.values())
    if total > MAX_GLSL_BYTES:
        raise ViewerError(f"{name}: its GLSL has {total:,} bytes; the shader and isFunc sections may have "
                          f"at most {_kb(MAX_GLSL_BYTES)} ({MAX_GLSL_BYTES:,} bytes) together")
    for ln, code in code_lines.items():
        for m in _ARRAY.finditer(code):
            if int(m.group(1)) > MAX_ARRAY:
                raise ViewerError(f"{name}:{ln}: an array of {int(m.group(1)):,} elements; at most "
                                  f"{MAX_ARRAY:,} in a .brdf file")
    check_loops(name, code_lines)


def _loops(code: str):
    """(keyword, offset of '(', offset of the matching ')', [offsets of ';' at depth 1]) of every
    loop header in ``code`` (comments already blanked)."""
    for m in _LOOP.finditer(code):
        start = m.end() - 1
        depth, semis, j = 0, [], start
        while j < len(code):
            c = code[j]
            if c == "(":
                depth += 1
            elif c == ")":
                depth -= 1
                if depth == 0:
                    break
            elif c == ";" and depth == 1:
                semis.append(j)
            j += 1
        if j < len(code):
            yield m.group(1), start, j, semis


def _joined(code_lines: dict[int, str]):
    """The code lines as one text (comments blanked, lengths kept) and each line's (number, offset)."""
    order = sorted(code_lines)
    text, starts, pos = [], [], 0
    for ln in order:
        text.append(code_lines[ln])
        starts.append((ln, pos))
        pos += len(code_lines[ln]) + 1
    joined = "\n".join(text)
    masked = re.sub(r"//[^\n]*|/\*.*?\*/", lambda m: re.sub(r"[^\n]", " ", m.group(0)), joined, flags=re.S)
    return masked, starts


def _line_of(starts, offset: int) -> int:
    ln = starts[0][0]
    for n, s in starts:
        if s > offset:
            break
        ln = n
    return ln


def check_loops(name: str, code_lines: dict[int, str]) -> None:
    """Refuse a loop whose condition is missing or always true, naming its line."""
    code, starts = _joined(code_lines)
    for kw, lo, hi, semis in _loops(code):
        if kw == "for":
            cond = code[semis[0] + 1:semis[1]] if len(semis) >= 2 else None
        else:
            cond = code[lo + 1:hi]
        if cond is not None and _ALWAYS.match(cond):
            what = "for (;;)" if kw == "for" else f"while ({cond.strip() or 'true'})"
            raise ViewerError(f"{name}:{_line_of(starts, lo)}: the loop {what} never ends; give it a condition "
                              f"that becomes false (a loop may run at most {MAX_LOOP_STEPS:,} steps in one call "
                              f"of BRDF)")


def guard_loops(code_lines: dict[int, str], step: str) -> dict[int, str]:
    """The code lines with every loop condition ``C`` made ``step() && (C)`` (an empty ``for``
    condition: ``step()``): each line keeps its number, text is only inserted."""
    code, starts = _joined(code_lines)
    inserts: list[tuple[int, str]] = []
    for kw, lo, hi, semis in _loops(code):
        if kw == "for":
            if len(semis) < 2:
                continue  # not a for header the compiler accepts: it reports it
            a, b = semis[0] + 1, semis[1]
        else:
            a, b = lo + 1, hi
        if code[a:b].strip():
            inserts += [(a, f"{step}() && ("), (b, ")")]
        else:
            inserts.append((a, f" {step}() "))
    if not inserts:
        return dict(code_lines)
    # apply on the original text (same offsets: comments were blanked, not removed)
    order = sorted(code_lines)
    original = "\n".join(code_lines[ln] for ln in order)
    out = []
    prev = 0
    for off, text in sorted(inserts, key=lambda t: t[0]):
        out.append(original[prev:off])
        out.append(text)
        prev = off
    out.append(original[prev:])
    new = "".join(out).split("\n")
    return dict(zip(order, new))


def guard_globals(prefix: str) -> str:
    """The GLSL (one line) of the loop budget of the file whose names carry ``prefix``."""
    return (f"int {prefix}0steps = 0; bool {prefix}0step() {{ {prefix}0steps += 1; "
            f"return {prefix}0steps <= {MAX_LOOP_STEPS}; }}")


def over_budget_glsl(prefix: str) -> str:
    """A GLSL bool expression: the last call of the file's entry point reached the loop budget."""
    return f"({prefix}0steps > {MAX_LOOP_STEPS})"


def over_budget_message(name: str) -> str:
    return (f"{name}: a loop of its GLSL ran past {MAX_LOOP_STEPS:,} steps in one call of BRDF (a loop must "
            f"end within {MAX_LOOP_STEPS:,} steps, all loops of one call together)")
