"""The window's BRDF Explorer parameter files and measured files: a ``.bparam`` loaded onto a
material or saved from it (``viewer.brdf.bparam``), a MERL ``.binary`` or MIT ``.dat`` table put
on a material. Each reports one line through ``session.notify``; a failure keeps the material."""

from __future__ import annotations

from viewer import ViewerError


def _model(params):
    import os

    from viewer import brdf

    if brdf.is_file(params):
        return brdf.load(os.fspath(params["file"]))
    return brdf.get(params.model)


def load_bparam(session, name: str, path) -> bool:
    """Set material ``name``'s values from a .bparam file (by name and kind; what it lacks: one note)."""
    from viewer.brdf import bparam

    try:
        params = session.scene.materials[name]
        new, note = bparam.apply(_model(params), params, bparam.parse(path))
    except ViewerError as e:
        session.notify(str(e).splitlines()[0], error=True)
        return False
    session.set_material(name, new)
    session.notify(f"material {name!r} <- values of {path}" + (f" ({note})" if note else ""))
    return True


def save_bparam(session, name: str, path) -> bool:
    """Write material ``name``'s values as a .bparam file (atomically)."""
    from viewer.brdf import bparam

    path = str(path) if str(path).lower().endswith(".bparam") else f"{path}.bparam"
    try:
        params = session.scene.materials[name]
        bparam.save(path, _model(params), params)
    except (ViewerError, OSError) as e:
        session.notify(str(e).splitlines()[0], error=True)
        return False
    session.notify(f"wrote {path} (the values of material {name!r})")
    return True


def load_measured(session, name: str, path) -> bool:
    """Put a measured table (MERL .binary or MIT .dat) on material ``name``."""
    from viewer import brdf

    try:
        params = brdf.get("measured").params(file=str(path))
    except ViewerError as e:
        session.notify(str(e).splitlines()[0], error=True)
        return False
    session.set_material(name, params)
    session.notify(f"material {name!r} <- measured table {path}")
    return True
