"""The scene's geometry for ray queries, shared by the reference engines and the rasterizer's
traced chains. No GL and no integrator here.

* ``soup``       ``build_geometry(scene)``: the scene as one world-space triangle soup with the
                 shading data (vertex normals, tangents, object and material per triangle), and
                 the hit-point / shading-frame helpers of the integrators
* ``bvh_build``  ``build_bvh(triangles)``: the binned SAH tree (numba) as flat arrays
* ``bvh_flat``   ``flatten_scene(geom)``: that tree and the triangles as float32 texel arrays for
                 the GPU's textures

The submodules are imported by name (``from viewer.geometry.soup import build_geometry``), so
importing the soup does not load numba.
"""
