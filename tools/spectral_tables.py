"""Regenerates the data files of ``viewer/spectral/data`` (run by hand; not used at run time).

    python tools/spectral_tables.py --ri-database PATH_TO/refractiveindex.info-database

* ``cie1931_d65.csv``: the CIE 1931 2 degree colour-matching functions (CIE 015:2018, 1 nm) and
  the CIE standard illuminant D65 (CIE S 014-2, 5 nm, linearly interpolated to 1 nm as CIE 015
  recommends), 360-780 nm, as colour-science (``colour.MSDS_CMFS``, ``colour.SDS_ILLUMINANTS``)
  holds them.
* ``<metal>.csv``: n, k tables of metals, 350-800 nm, from the refractiveindex.info database
  (public domain, CC0), each with the reference of the measurement it reproduces.
* ``rgb_basis.csv``: the three spectra of the RGB upsampling (``viewer.spectral.upsampling``).
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

DATA = pathlib.Path(__file__).resolve().parents[1] / "viewer" / "spectral" / "data"

METALS = {  # name -> (file in the database, reference)
    "Au": ("main/Au/nk/Johnson.yml", "P. B. Johnson and R. W. Christy, Optical constants of the noble metals, Phys. Rev. B 6, 4370-4379 (1972), doi:10.1103/PhysRevB.6.4370"),
    "Ag": ("main/Ag/nk/Johnson.yml", "P. B. Johnson and R. W. Christy, Optical constants of the noble metals, Phys. Rev. B 6, 4370-4379 (1972), doi:10.1103/PhysRevB.6.4370"),
    "Cu": ("main/Cu/nk/Johnson.yml", "P. B. Johnson and R. W. Christy, Optical constants of the noble metals, Phys. Rev. B 6, 4370-4379 (1972), doi:10.1103/PhysRevB.6.4370"),
    "Al": ("main/Al/nk/Rakic.yml", "A. D. Rakic, Algorithm for the determination of intrinsic optical constants of metal films: application to aluminum, Appl. Opt. 34, 4755-4767 (1995), doi:10.1364/AO.34.004755"),
    "Cr": ("main/Cr/nk/Johnson.yml", "P. B. Johnson and R. W. Christy, Optical constants of transition metals: Ti, V, Cr, Mn, Fe, Co, Ni, and Pd, Phys. Rev. B 9, 5056-5070 (1974), doi:10.1103/PhysRevB.9.5056"),
    "Fe": ("main/Fe/nk/Johnson.yml", "P. B. Johnson and R. W. Christy, Optical constants of transition metals: Ti, V, Cr, Mn, Fe, Co, Ni, and Pd, Phys. Rev. B 9, 5056-5070 (1974), doi:10.1103/PhysRevB.9.5056"),
    "Ti": ("main/Ti/nk/Johnson.yml", "P. B. Johnson and R. W. Christy, Optical constants of transition metals: Ti, V, Cr, Mn, Fe, Co, Ni, and Pd, Phys. Rev. B 9, 5056-5070 (1974), doi:10.1103/PhysRevB.9.5056"),
}


def cie_tables():
    import colour

    wl = np.arange(360, 781, dtype=np.float64)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    xyz = np.array([cmfs[w] for w in wl])
    d65 = colour.SDS_ILLUMINANTS["D65"]
    s = np.interp(wl, d65.wavelengths, d65.values)
    rows = np.column_stack([wl, xyz, s])
    head = ("# CIE 1931 2 degree standard observer (CIE 015:2018) and CIE illuminant D65 (CIE S 014-2,\n"
            "# 5 nm, linearly interpolated to 1 nm), as held by colour-science 0.4 (colour.MSDS_CMFS,\n"
            "# colour.SDS_ILLUMINANTS); written by tools/spectral_tables.py\n"
            "wavelength_nm,x_bar,y_bar,z_bar,D65\n")
    text = head + "".join(f"{int(r[0])},{r[1]:.6e},{r[2]:.6e},{r[3]:.6e},{r[4]:.4f}\n" for r in rows)
    (DATA / "cie1931_d65.csv").write_text(text)


def metal_tables(db: pathlib.Path):
    for name, (rel, ref) in METALS.items():
        lines = (db / "database" / "data" / rel).read_text().splitlines()
        start = next(i for i, line in enumerate(lines) if "type: tabulated nk" in line) + 2
        rows = []
        for line in lines[start:]:
            parts = line.split()
            if len(parts) != 3:
                break
            rows.append([float(v) for v in parts])
        arr = np.array(rows)
        wl = arr[:, 0] * 1000.0
        # keep the visible range and one sample beyond each end
        lo = max(0, np.searchsorted(wl, 350.0) - 1)
        hi = min(len(wl), np.searchsorted(wl, 800.0) + 1)
        arr = arr[lo:hi]
        head = (f"# {name}: complex index of refraction n + i k, room temperature\n"
                f"# source: {ref}\n"
                f"# via the refractiveindex.info database ({rel}; public domain, CC0 1.0)\n"
                "wavelength_nm,n,k\n")
        text = head + "".join(f"{r[0] * 1000.0:.2f},{r[1]:.6g},{r[2]:.6g}\n" for r in arr)
        (DATA / f"{name}.csv").write_text(text)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ri-database", type=pathlib.Path, help="a checkout of refractiveindex.info-database")
    ap.add_argument("--basis", action="store_true", help="recompute rgb_basis.csv from the CIE tables")
    args = ap.parse_args()
    cie_tables()
    if args.ri_database:
        metal_tables(args.ri_database)
    if args.basis:
        from viewer.spectral import upsampling

        upsampling.write_basis(DATA / "rgb_basis.csv")
