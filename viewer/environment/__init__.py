"""Environment lighting, the CPU side: map files, built-in maps, lat-long geometry, spherical
harmonics irradiance and the split-sum DFG table.

* ``io``: ``load_environment`` / ``save_environment`` for Radiance .hdr and OpenEXR .exr.
* ``procedural``: built-in maps ``sky`` (Preetham 1999 + sun) and ``studio``, and ``constant``.
* ``latlong``: direction <-> (u, v), rotation about +y, bilinear lookup, texel solid angles,
  and ``to_cubemap`` in OpenGL's face order (the numpy reference for the GPU path).
* ``sh``: order-2 SH projection and irradiance (Ramamoorthi & Hanrahan 2001).
* ``dfg``: the (NoV, alpha) -> (A, B) table of Karis 2013 and Fdez-Agüera 2019's
  multiple-scattering compensation.

Orientation everywhere (docs/conventions.md): u = 0.5 + atan2(d.x, -d.z) / (2 pi),
v = acos(d.y) / pi, row 0 = zenith.
"""

from viewer.environment.io import load_environment, read_environment, save_environment
from viewer.environment.latlong import dir_to_uv, lookup, solid_angles, to_cubemap, uv_to_dir
from viewer.environment.procedural import builtin_names, generate

__all__ = ["load_environment", "read_environment", "save_environment", "dir_to_uv", "uv_to_dir",
           "lookup", "solid_angles", "to_cubemap", "builtin_names", "generate"]
