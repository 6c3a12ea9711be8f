"""The probe's child process (``viewer.brdf.twin_trust.probe``): import a trusted numpy twin and
evaluate it once at a few direction pairs with the file's default parameters (``sample`` and
``pdf`` too when it has them), through the same checks as in the program, and write the verdict
as one JSON line after ``twin_trust.VERDICT``. The parent kills it past the time limit."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

#: direction pairs of the first eval (upper hemisphere, normalized below)
WI = np.array([[0.0, 0.0, 1.0], [0.5, 0.1, 0.8], [-0.3, 0.6, 0.5], [0.9, 0.0, 0.2]])
WO = np.array([[0.0, 0.0, 1.0], [-0.4, 0.2, 0.7], [0.1, -0.7, 0.4], [0.2, 0.9, 0.3]])


def try_twin(twin: Path, brdf_path: Path) -> None:
    from viewer.brdf import FileModel
    from viewer.brdf import twin_trust
    from viewer.brdf.brdffile import parse
    from viewer.brdf.file_model import make_module

    bfile = parse(brdf_path)
    p = FileModel(make_module(bfile), where=brdf_path.name).params()
    mod = twin_trust.import_twin(twin)
    ev, sample, pdf = twin_trust.guarded(twin, mod)
    wi = WI / np.linalg.norm(WI, axis=1, keepdims=True)
    wo = WO / np.linalg.norm(WO, axis=1, keepdims=True)
    ev(p, wi, wo)
    if sample is not None:
        u = np.array([[0.1, 0.2], [0.5, 0.5], [0.9, 0.3], [0.3, 0.8]])
        sample(p, wo, u)
        pdf(p, wi, wo)


def main(argv) -> int:
    from viewer import ViewerError
    from viewer.brdf.twin_trust import VERDICT

    twin, brdf_path = Path(argv[0]), Path(argv[1])
    try:
        try_twin(twin, brdf_path)
        answer = {"ok": True}
    except ViewerError as e:
        answer = {"ok": False, "error": str(e).splitlines()[0] if str(e) else f"{twin.name}: failed"}
    except BaseException as e:  # noqa: BLE001 - anything else is still the twin's, in one line
        answer = {"ok": False, "error": f"{twin.name}: {type(e).__name__}: {e}"}
    sys.stdout.write("\n" + VERDICT + json.dumps(answer) + "\n")
    sys.stdout.flush()
    return 0
