"""The session's actions on files and on what they hold: scenes (open, save), materials (edit,
load, save), meshes, environment maps, files dropped on the window. Each keeps what was shown
when it fails and says why through ``notify`` (one message naming the file and the problem).

``FileActions`` is held by ``viewer.app.session.Session`` as ``session.files`` (it uses the
session's ``scene``, ``camera``, ``renderer``, ``dirty`` and ``notify``). No imgui, no glfw."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.gl.shadow import unshadowed_note

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
ENV_SUFFIXES = (".hdr", ".exr")
SCENE_SUFFIXES = (".toml", ".png")


#: folders whose .brdf files the material picker offers beside the presets (after the shipped
#: viewer/brdfs): the folder of each .brdf file the window opens joins it
BRDF_LIBRARY: list[str] = []


class FileActions:
    """Scenes, materials, meshes and environment maps of the ``Session`` ``session``."""

    def __init__(self, session):
        self.session = session
        self._mesh_target = None

    # ------------------------------------------------------------------ materials
    def set_material(self, name: str, params) -> None:
        """Replace material ``name`` with validated ``params`` (the editor's result). A mirror
        or smooth glass arriving while reflections are not traced says what shows it."""
        from viewer.app.reflections import delta_materials, traced_hint

        s = self.session
        was = name in delta_materials(s.scene)
        s.scene.materials[name] = params
        s.dirty = True
        if getattr(s, "twins", None) is not None:  # a file material whose twin is not trusted: ask
            s.twins.scan_material(params)
        if not was and name in delta_materials(s.scene) and traced_hint(s.scene):
            s.notify(traced_hint(s.scene))

    def set_material_param(self, name: str, param: str, value) -> bool:
        """Set one parameter of material ``name``, validated through the model's spec: NaN, Inf,
        a value out of range or an unknown choice leaves the old value and notifies once."""
        from viewer import brdf
        from viewer.brdf.spec import validate_value

        s = self.session
        mat = s.scene.materials.get(name)
        if mat is None:
            s.notify(f"material {name!r}: not in the scene; it has {', '.join(s.scene.materials)}", error=True)
            return False
        spec = brdf.spec_of(mat)
        by_name = {p.name: p for p in spec.params}
        p = by_name.get(param)
        if p is None:
            s.notify(f"{mat.model}.{param}: unknown parameter; allowed: {', '.join(by_name)}", error=True)
            return False
        try:
            if p.kind in ("float", "rgb", "choice"):
                value = validate_value(p, list(np.asarray(value, float).reshape(-1)) if p.kind == "rgb" else value,
                                       f"{mat.model}.{p.name}", brdf.lookup_spec)
        except (ViewerError, TypeError, ValueError) as e:
            s.notify(str(e) if isinstance(e, ViewerError) else f"{mat.model}.{param}: {e}", error=True)
            return False
        self.set_material(name, mat.replace(**{param: value}))
        return True

    def save_material(self, name: str, path) -> bool:
        """One material as a ``[materials.NAME]`` table (the scene file's format)."""
        from viewer.base.io import atomic_write_bytes
        from viewer.scene import material_to_toml

        s = self.session
        try:
            text = material_to_toml(name, s.scene.materials[name])
            atomic_write_bytes(Path(path).expanduser(), text.encode("utf-8"))
        except (OSError, KeyError, ViewerError) as e:
            s.notify(f"material not saved: {e}", error=True)
            return False
        s.notify(f"saved material {name} to {path}")
        return True

    def load_material(self, name: str, path) -> bool:
        """Replace material ``name`` with the first material of a TOML file (a material file or
        a whole scene), validated like a scene's; on any problem the old material stays."""
        from viewer.scene import load_material_file

        s = self.session
        try:
            first, params = load_material_file(path)
        except ViewerError as e:
            s.notify(f"material not loaded: {e}", error=True)
            return False
        s.scene.materials[name] = params
        s.dirty = True
        s.notify(f"material {name} <- {path} [{first}]")
        return True

    # ------------------------------------------------------------------ scenes and meshes
    def set_scene(self, scene):
        """Show ``scene``: a new camera on it, the old scene's mesh buffers freed, drawn anew."""
        from viewer.scene.camera import OrbitCamera

        s = self.session
        s.renderer.forget_meshes(keep=[o.mesh_data for o in scene.objects])  # the old scene's buffers
        s.scene = scene
        s.camera = OrbitCamera.from_scene(scene)
        s.hdr = None
        s.dirty = True
        if getattr(s, "twins", None) is not None:  # its file materials' untrusted twins: ask
            s.twins.scan(scene)

    def open_scene(self, ref) -> bool:
        """Load a scene file, a screenshot (.png) or a built-in name; on failure keep the old."""
        from viewer.scene import load_scene

        s = self.session
        try:
            scene = load_scene(str(ref))
        except ViewerError as e:
            s.notify(f"scene not opened: {e}", error=True)
            return False
        except Exception as e:  # noqa: BLE001 - anything unexpected keeps the running scene
            s.notify(f"scene not opened: {ref}: {type(e).__name__}: {e}", error=True)
            return False
        self.set_scene(scene)
        s.lecture_step = -1
        notes = [n for n in (scene.size_note(), unshadowed_note(scene)) if n]   # how large; lights unshadowed
        s.notify(f"opened {ref}" + (f" ({'; '.join(notes)})" if notes else ""))
        return True

    def save_scene(self, path) -> bool:
        """The current scene (camera as seen) as TOML in the scene-file format, written atomically."""
        from viewer.base.io import atomic_write_bytes
        from viewer.scene import scene_to_toml
        from viewer.scene.screenshot import scene_with_camera

        s = self.session
        try:
            text = scene_to_toml(scene_with_camera(s.scene, s.camera))
            atomic_write_bytes(Path(path).expanduser(), text.encode("utf-8"))
        except (OSError, ViewerError) as e:
            s.notify(f"scene not saved: {e}", error=True)
            return False
        s.notify(f"saved scene {path}")
        return True

    @property
    def mesh_target(self) -> int:
        """The object a loaded mesh replaces: the one picked in the panel, else the largest
        object that is not a plane."""
        s = self.session
        if self._mesh_target is not None and self._mesh_target < len(s.scene.objects):
            return self._mesh_target
        best, best_r = 0, -1.0
        for i, o in enumerate(s.scene.objects):
            if o.mesh == "plane":
                continue
            p = o.world_positions()
            r = float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))
            if r > best_r:
                best, best_r = i, r
        return best

    @mesh_target.setter
    def mesh_target(self, index: int | None) -> None:
        self._mesh_target = index

    def load_mesh(self, path, object_index: int | None = None) -> bool:
        """Replace one object's mesh (default: the largest object that is not a plane) with a
        mesh file, scaled to the same bounding-sphere radius and centre; errors keep the old."""
        from viewer.scene.mesh import load_mesh

        session = self.session
        objs = session.scene.objects
        if not objs:
            session.notify("mesh not loaded: the scene has no objects", error=True)
            return False
        if object_index is None:
            object_index = self.mesh_target
        object_index = int(np.clip(object_index, 0, len(objs) - 1))
        obj = objs[object_index]
        try:
            md = load_mesh(str(Path(path).expanduser().absolute()), None, where="Files > Load mesh")
        except ViewerError as e:
            session.notify(f"mesh not loaded: {e}", error=True)
            return False
        except Exception as e:  # noqa: BLE001 - trimesh raises many kinds for a broken file
            session.notify(f"mesh not loaded: {path}: {type(e).__name__}: {e}", error=True)
            return False

        def sphere(points):
            lo, hi = points.min(axis=0), points.max(axis=0)
            return (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-12)

        old_c, old_r = sphere(obj.world_positions())
        new_c, new_r = sphere(np.asarray(md.positions, np.float64).reshape(-1, 3))
        s = old_r / new_r
        obj.mesh = str(Path(path).expanduser().absolute())
        obj.mesh_data = md
        session.renderer.forget_meshes(keep=[o.mesh_data for o in objs])
        obj.scale = s
        obj.rotate_y_deg = 0.0
        obj.translate = old_c - s * new_c
        session.dirty = True
        session.notify(f"object {object_index} <- {path} ({len(md.indices):,} triangles)")
        return True

    def file_action(self, kind: str, path: str) -> bool:
        """A path picked or typed under Files: open / save a scene, load a mesh, load / save the
        material of the object meshes replace."""
        s = self.session
        target = s.scene.objects[self.mesh_target].material if s.scene.objects else None
        if kind == "scene":
            return self.open_scene(path)
        if kind == "save_scene":
            return self.save_scene(path if path.lower().endswith(".toml") else path + ".toml")
        if kind == "mesh":
            return self.load_mesh(path)
        if kind == "material" and target:
            return self.load_material(target, path)
        if kind in ("bparam", "save_bparam", "measured") and target:
            from viewer.app import param_files

            fn = {"bparam": param_files.load_bparam, "save_bparam": param_files.save_bparam,
                  "measured": param_files.load_measured}[kind]
            return fn(s, target, path)
        if kind == "save_material" and target:
            return self.save_material(target, path if path.lower().endswith(".toml") else path + ".toml")
        return False

    def open_files(self, paths) -> None:
        """Files dropped on the window, each by its kind: .toml / .png scenes, .hdr / .exr
        environment maps, meshes, .brdf files; .bparam values and .binary / .dat measured tables
        go onto the selected object's material."""
        for p in paths:
            low = p.lower()
            if os.path.isdir(p):  # a folder of .brdf files: a library for the material picker
                self.open_brdf_library(p)
            elif low.endswith(ENV_SUFFIXES):
                self.set_environment(p)
            elif low.endswith(SCENE_SUFFIXES):
                self.open_scene(p)
            elif low.endswith(MESH_SUFFIXES):
                self.load_mesh(p)
            elif low.endswith(".brdf"):
                self.load_brdf_file(p)
            elif low.endswith((".bparam", ".binary", ".dat")):  # onto the selected object's material
                self.file_action("bparam" if low.endswith(".bparam") else "measured", p)
            else:
                self.session.notify(f"dropped {p}: unknown kind; allowed: .toml/.png scenes, .hdr/.exr maps, "
                                    ".brdf files or a folder of them, .bparam values, .binary / .dat measured "
                                    "tables, meshes " + " ".join(MESH_SUFFIXES), error=True)

    def open_brdf_library(self, folder) -> bool:
        """A folder of ``.brdf`` files: its files join the material picker beside the presets
        (``file: NAME.brdf``), each loaded when picked. A folder without one is one error."""
        s = self.session
        folder = os.path.abspath(os.path.expanduser(str(folder)))
        names = sorted(f for f in os.listdir(folder) if f.lower().endswith(".brdf")) if os.path.isdir(folder) else []
        if not names:
            s.notify(f"{folder}: no .brdf files in the folder", error=True)
            return False
        if folder not in BRDF_LIBRARY:
            BRDF_LIBRARY.append(folder)
        s.notify(f"{len(names)} .brdf files from {folder} in the material picker")
        return True

    def load_brdf_file(self, path, name: str | None = None) -> bool:
        """Put a BRDF Explorer ``.brdf`` file (its declared defaults) on material ``name`` (default:
        the material of the selected object, ``mesh_target``). A file that does not parse or
        compile keeps the material and reports one line naming ``FILE.brdf:LINE``."""
        from viewer import brdf, file_brdf_evaluator

        s = self.session
        if name is None:
            if not s.scene.objects:
                s.notify(f"{path}: the scene has no object to put it on", error=True)
                return False
            name = s.scene.objects[self.mesh_target].material
        try:
            model = brdf.load(path)
            file_brdf_evaluator().check(model.bfile)
            params = model.params()
        except ViewerError as e:
            s.notify(str(e).splitlines()[0], error=True)
            return False
        folder = str(model.bfile.path.parent)
        if folder not in BRDF_LIBRARY:  # its neighbours join the picker's file materials
            BRDF_LIBRARY.append(folder)
        self.set_material(name, params)
        s.notify(f"material {name!r} <- {model.bfile.path.name} ({len(model.bfile.declarations)} parameters)")
        return True

    def refit_file_materials(self) -> list[str]:
        """Fit every file material to its ``.brdf`` file as it is now (after hot reload saw the
        file saved with parameters added, removed, renamed or retyped): values whose name and
        kind still match are kept, the others start at the file's defaults
        (``viewer.brdf.file_carry``). Returns the names of the materials that changed."""
        from viewer.brdf.file_carry import carry_over

        s = self.session
        changed = []
        for name, params in list(s.scene.materials.items()):
            fitted = carry_over(params)
            if fitted is not params:
                s.scene.materials[name] = fitted
                changed.append(name)
        if changed:
            s.dirty = True
        return changed

    # ------------------------------------------------------------------ environment
    def set_environment(self, ref) -> bool:
        """Switch the environment to a built-in map name, a .hdr/.exr path or None (constant).
        A file that does not load leaves the previous environment and shows why."""
        s = self.session
        env = s.scene.environment
        new = dataclasses.replace(env)
        new.__dict__.pop("_map_cache", None)
        if ref is None:
            new.map = None
            if new.constant is None:
                new.constant = np.array([0.1, 0.1, 0.1])
        else:
            from viewer.environment.procedural import builtin_names

            new.map = ref if ref in builtin_names() else Path(ref).expanduser()
            new.constant = None
            try:
                new.radiance_map()
            except ViewerError as e:
                s.notify(f"environment not changed: {e}", error=True)
                return False
            except Exception as e:  # noqa: BLE001 - any decoder failure keeps the old map
                s.notify(f"environment not changed: {ref}: {type(e).__name__}: {e}", error=True)
                return False
        s.scene.environment = new
        text = f"environment: {ref or 'constant'}"
        if new.map is not None:  # a map's own units (the sky is in kcd/m^2): start at mid-grey
            auto = new.mid_grey_intensity()
            if auto is not None:
                new.intensity = float(auto)
                text += (f" (intensity {auto:.3g}: mean luminance {new.mean_luminance():.3g} -> mid-grey "
                         "0.18; edit it under Environment)")
        s.notify(text)
        s.dirty = True
        return True
