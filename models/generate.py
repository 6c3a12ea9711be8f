"""Write every built-in shape of viewer.scene.meshgen to models/<name>.ply.

    python models/generate.py            # all shapes
    python models/generate.py teapot     # only some

Binary little-endian PLY: float32 x y z nx ny nz (and s t where the shape has uvs),
uint32 triangles. The files are what the product ships; viewer.scene.mesh.load_mesh("teapot")
reads them, and gives the same mesh as the in-memory generator when they are absent.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from viewer.scene import meshgen  # noqa: E402
from viewer.scene.mesh import write_ply  # noqa: E402


def main(argv: list[str]) -> int:
    names = argv or list(meshgen.GENERATORS)
    unknown = [n for n in names if n not in meshgen.GENERATORS]
    if unknown:
        print(f"unknown shape(s): {', '.join(unknown)} (known: {', '.join(meshgen.GENERATORS)})",
              file=sys.stderr)
        return 2
    total = 0
    for name in names:
        shape = meshgen.generate(name)
        out = HERE / f"{name}.ply"
        write_ply(out, shape.positions, shape.normals, shape.indices, shape.uvs)
        size = out.stat().st_size
        total += size
        print(f"{out.name:26s} {len(shape.positions):7d} vertices {len(shape.indices):7d} faces "
              f"{size / 1024:8.1f} KiB")
    print(f"total {total / 1024 / 1024:.2f} MiB")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
