"""Build hook: the top-level ``shaders/`` and ``models/`` folders are copied into the built
package as ``viewer/shaders`` and ``viewer/models``, so a wheel (and an install from the sdist)
carries them; in a source checkout ``viewer.base.resources`` reads the top-level folders directly.
Everything else is declared in pyproject.toml."""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
# folder in the checkout -> (folder inside the package, the files that ship)
RESOURCES = {"shaders": ("shaders", ("*.glsl", "*.vert", "*.frag", "*.geom")),
             "models": ("models", ("*.ply",))}


class BuildPyWithResources(build_py):
    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return  # an editable install reads the checkout's folders (viewer/base/resources.py)
        for src_name, (dst_name, patterns) in RESOURCES.items():
            src = HERE / src_name
            dst = Path(self.build_lib) / "viewer" / dst_name
            if dst.exists():
                shutil.rmtree(dst)
            for pattern in patterns:
                for f in sorted(src.rglob(pattern)):
                    target = dst / f.relative_to(src)
                    target.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copy2(f, target)


setup(cmdclass={"build_py": BuildPyWithResources})
