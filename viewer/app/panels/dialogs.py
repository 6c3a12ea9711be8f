"""The desktop's own file dialogs (zenity / kdialog on Linux through imgui-bundle's
portable_file_dialogs), opened without blocking and polled once a frame."""

from __future__ import annotations

from pathlib import Path


def open_dialog(session, title: str, filters: list[str], save: bool = False):
    """A dialog object to poll with ``picked``, or None (and an error notification) when the
    desktop has no dialog backend."""
    try:
        from imgui_bundle import portable_file_dialogs as pfd

        if save:
            return pfd.save_file(title, str(Path.cwd()), filters)
        return pfd.open_file(title, str(Path.cwd()), filters)
    except Exception as e:  # noqa: BLE001 - no dialog backend: say so, keep going
        session.notify(f"no file dialog available ({e}); type a path or drop a file", error=True)
        return None


def picked(dialog):
    """(done, path): done once the dialog closed; path is "" when nothing was picked."""
    if dialog is None or not dialog.ready(0):
        return False, ""
    result = dialog.result()
    if isinstance(result, list):
        result = result[0] if result else ""
    return True, result or ""
