"""The window's question before a ``.brdf`` file's numpy twin runs (``viewer.brdf.twin_trust``).

A twin is Python code that came with the file; the window runs it only when the user says so.
When a file whose twin is not trusted is opened (the scene at start, a dropped file or folder, a
scene or screenshot opened, a file picked from the material picker) the session keeps the
question, naming the twin, until the user answers it (the dialog: ``panels/twin_dialog.py``):
*Run its Python twin* trusts the twin's folder, for this session and, remembered in the state
file (``trusted_twin_folders``), for the next; *Not now* leaves the file working without its twin
and does not ask again about that folder in this session. Nothing here imports imgui.
"""

from __future__ import annotations

import threading
from pathlib import Path

from viewer.brdf import twin_trust

STATE_KEY = "trusted_twin_folders"


def trust_remembered(state: dict) -> list[Path]:
    """Trust the folders the user let run twins in earlier sessions (those that still exist)."""
    out = []
    for folder in state.get(STATE_KEY, ()) or ():
        if isinstance(folder, str) and Path(folder).is_dir():
            out.append(twin_trust.trust(folder))
    return out


class TwinQuestion:
    """The twins waiting for the user's answer, first asked first. ``current``: (the ``.brdf``
    file, its twin) asked now, or None."""

    def __init__(self, session):
        self.session = session
        self._lock = threading.Lock()
        self._pending: list[tuple[Path, Path]] = []
        self._declined: set[Path] = set()
        trust_remembered(session.state)
        twin_trust.set_listener(self.heard)
        self.scan(session.scene)

    @property
    def current(self) -> tuple[Path, Path] | None:
        with self._lock:
            return self._pending[0] if self._pending else None

    def question(self) -> str:
        """The question's text for ``current`` ("" when none)."""
        cur = self.current
        if cur is None:
            return ""
        brdf_path, twin = cur
        return (f"{brdf_path.name} comes with a numpy twin, {twin_trust.real(twin)}: Python code that runs with "
                f"your rights. Run it? Without it the file still works (the gpu engine renders its reference). "
                f"Yes trusts the twins of {twin_trust.real(twin).parent} from now on.")

    def heard(self, brdf_path: Path, twin: Path, message: str) -> None:
        """``twin_trust``'s listener: a file's twin was not run (any thread)."""
        folder = twin_trust.real(twin).parent
        with self._lock:
            if folder in self._declined or any(t == twin for _, t in self._pending):
                return
            self._pending.append((Path(brdf_path), Path(twin)))
        self.session.notify(message)

    def scan(self, scene) -> None:
        """Ask about the twins of ``scene``'s file materials that are not trusted (those loaded
        before the listener was set, or earlier in this process)."""
        for p in scene.materials.values():
            self.scan_material(p)

    def scan_material(self, p) -> None:
        from viewer import ViewerError, brdf

        if not brdf.is_file(p):
            return
        try:
            model = brdf.get("custom").of(p)
        except ViewerError:
            return  # the file's own problem is reported where it is drawn
        twin = twin_trust.twin_of(model.bfile.path)
        if model.twin_not_run and not twin_trust.is_trusted(twin):
            self.heard(model.bfile.path, twin, model.twin_not_run)

    def answer(self, run: bool) -> None:
        """The user's answer to ``current``: run it (trust its folder, remembered), or not now."""
        with self._lock:
            if not self._pending:
                return
            brdf_path, twin = self._pending.pop(0)
            folder = twin_trust.real(twin).parent
            if not run:
                self._declined.add(folder)
                self._pending = [(b, t) for b, t in self._pending if twin_trust.real(t).parent != folder]
        if not run:
            self.session.notify(f"{brdf_path.name}: its numpy twin {twin.name} was not run (not now); the file "
                                f"works without it")
            return
        twin_trust.trust(folder)
        kept = [f for f in self.session.state.get(STATE_KEY, []) if f != str(folder)]
        self.session.state[STATE_KEY] = kept + [str(folder)]
        with self._lock:
            self._pending = [(b, t) for b, t in self._pending if not twin_trust.is_trusted(t)]
        self.session.changed()
        from viewer import ViewerError, brdf

        try:
            brdf.load(brdf_path)  # a twin that misbehaves says so now, in one line
        except ViewerError as e:
            self.session.notify(str(e).splitlines()[0], error=True)
            return
        self.session.notify(f"{brdf_path.name}: its numpy twin {twin.name} runs; the twins of {folder} are "
                            f"trusted (remembered)")

    def release(self) -> None:
        twin_trust.set_listener(None)
