"""Compile time of a layered material's programs with and without a thin film on its coating,
on this machine's OpenGL (software GL: llvmpipe). The coat film's reflectance comes from tables
computed on the CPU (viewer/brdf/layered.py ``film_table``), so its GLSL has no wavelength loop
and should compile in about the time of a plain coat. One command:

    MESA_SHADER_CACHE_DISABLE=true python benchmarks/coat_film_compile.py

Prints, per base and coat, the seconds of the first raster frame (the forward program's compile
dominates it) and of the first GPU albedo table (the sampling program's compile). Measured here
(llvmpipe, 2 cores): Lambert base 1.2 / 1.0 s plain, 0.6 / 1.2 s with a 400 nm film; GGX base
1.6 / 1.5 s, 1.9 / 2.1 s. With the film's 32-wavelength loop inlined at every coat Fresnel call
instead, the Lambert base's forward program took 587 s (275 s even without a film).
"""

import time

from viewer import brdf

SCENE = """
[camera]
position = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
width = 16
height = 16
[render]
ibl = "off"
shadows = false
msaa = 1
[[lights]]
type = "directional"
direction = [0.0, 0.0, -1.0]
irradiance = [3.0, 3.0, 3.0]
[[objects]]
mesh = "sphere"
material = "m"
[materials.m]
model = "layered"
base = BASE
coating = COAT
"""

BASES = {"lambert": '{ model = "lambert", albedo = [0.5, 0.3, 0.2] }',
         "microfacet": '{ model = "microfacet", alpha = 0.3, fresnel = "conductor" }'}
COATS = {"plain": "{ ior = 1.5, alpha = 0.1 }",
         "film": "{ ior = 1.5, alpha = 0.1, thin_film = { ior = 1.33, thickness_nm = 400.0 } }"}


def main():
    import tomllib

    import viewer
    from viewer.gl.albedo_gpu import GPUAlbedoTables
    from viewer.gl.context import create_offscreen_context

    ctx = create_offscreen_context()
    tables = GPUAlbedoTables(ctx)
    M = brdf.get("layered")
    for bname, base in BASES.items():
        for cname, coat in COATS.items():
            scene = SCENE.replace("BASE", base).replace("COAT", coat)
            t0 = time.perf_counter()
            viewer.render(scene, width=16, height=16)
            t1 = time.perf_counter()
            m = tomllib.loads(scene)["materials"]["m"]
            p = M.params(coating=m["coating"], base=m["base"])
            t2 = time.perf_counter()
            tables.tables(p)
            t3 = time.perf_counter()
            print(f"{bname:10s} {cname:5s}: forward frame {t1 - t0:6.1f} s   GPU albedo table {t3 - t2:6.1f} s",
                  flush=True)


if __name__ == "__main__":
    main()
