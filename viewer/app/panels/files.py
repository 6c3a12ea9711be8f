"""The side panel's *Files* section: open / save scenes, load meshes, load / save materials by a
typed path or the desktop's file dialog; reopen the last session."""

from __future__ import annotations

from imgui_bundle import imgui

from viewer.app.panels.dialogs import open_dialog, picked

FILTERS = {
    "scene": ["Scenes and screenshots", "*.toml *.png", "All files", "*"],
    "save_scene": ["Scene (.toml)", "*.toml"],
    "mesh": ["Meshes", "*.obj *.ply *.stl *.off *.glb *.gltf", "All files", "*"],
    "material": ["Materials and scenes (.toml)", "*.toml", "All files", "*"],
    "save_material": ["Material (.toml)", "*.toml"],
    "bparam": ["BRDF Explorer parameters (.bparam)", "*.bparam", "All files", "*"],
    "save_bparam": ["BRDF Explorer parameters (.bparam)", "*.bparam"],
    "measured": ["Measured BRDFs (.binary, .dat)", "*.binary *.dat", "All files", "*"],
}


class FilesPanel:
    def __init__(self, session):
        self.session = session
        self.text = ""        # the path typed
        self.dialog = None    # (kind, an open file dialog)

    def poll(self) -> None:
        if self.dialog is None:
            return
        done, path = picked(self.dialog[1])
        if done:
            kind, self.dialog = self.dialog[0], None
            if path:
                self.session.file_action(kind, path)

    def open_or_browse(self, kind: str, path: str) -> None:
        if path:
            self.session.file_action(kind, path)
            return
        dlg = open_dialog(self.session, kind.replace("_", " "), FILTERS[kind], save=kind.startswith("save"))
        if dlg is not None:
            self.dialog = (kind, dlg)

    def draw(self) -> None:
        from viewer.app import state as state_mod

        s = self.session
        if not imgui.collapsing_header("Files"):
            return
        _, self.text = imgui.input_text("path##files", self.text)
        names = [f"{i}: {o.mesh if len(o.mesh) < 24 else '...' + o.mesh[-21:]} ({o.material})"
                 for i, o in enumerate(s.scene.objects)]
        ch, i = imgui.combo("object", s.mesh_target, names)
        if ch:
            s.mesh_target = i
        mats = list(s.scene.materials)
        mat = s.scene.objects[s.mesh_target].material if s.scene.objects else (mats[0] if mats else "")
        path = self.text.strip()
        if imgui.button("Open scene"):
            self.open_or_browse("scene", path)
        imgui.same_line()
        if imgui.button("Save scene"):
            self.open_or_browse("save_scene", path)
        imgui.same_line()
        if imgui.button("Load mesh"):
            self.open_or_browse("mesh", path)
        if mat:
            if imgui.button(f"Save material '{mat}'"):
                self.open_or_browse("save_material", path)
            imgui.same_line()
            if imgui.button("Load material"):
                self.open_or_browse("material", path)
            imgui.same_line()
            if imgui.button("Load measured"):
                self.open_or_browse("measured", path)
            from viewer import brdf

            if brdf.is_file(s.scene.materials.get(mat)):  # BRDF Explorer's parameter files
                if imgui.button("Load parameters (.bparam)"):
                    self.open_or_browse("bparam", path)
                imgui.same_line()
                if imgui.button("Save parameters (.bparam)"):
                    self.open_or_browse("save_bparam", path)
        if state_mod.last_scene_path().exists() and imgui.button("Reopen last session"):
            s.open_scene(state_mod.last_scene_path())
        imgui.text_disabled("empty path: a file dialog; or drop files on the window")
