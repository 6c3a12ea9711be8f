"""The side panel's *Scene* section: what is loaded, how long a frame takes, the camera."""

from __future__ import annotations

from imgui_bundle import imgui


def count_noun(n: int, noun: str) -> str:
    """'1 light', '2 lights', '12,345 triangles'."""
    return f"{n:,} {noun}" + ("" if n == 1 else "s")


def draw(session, frame_ms: float) -> None:
    s = session.scene
    if not imgui.collapsing_header("Scene", imgui.TreeNodeFlags_.default_open):
        return
    imgui.text(f"file: {s.label}")
    tris = sum(len(o.mesh_data.indices) for o in s.objects)
    imgui.text(f"{count_noun(len(s.objects), 'object')}, {count_noun(tris, 'triangle')}, "
               f"{count_noun(len(s.lights), 'light')}")
    imgui.text(f"render {session.render_ms:.1f} ms, frame {frame_ms:.1f} ms")
    imgui.text_wrapped(f"GL: {session.ctx.info['GL_RENDERER']}")
    if imgui.button("Reset camera (R)"):
        session.reset_camera()
    imgui.same_line()
    if imgui.button("Fit scene"):
        session.fit_camera()
