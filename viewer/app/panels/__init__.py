"""The window's panels, one module each. A panel draws the session (``viewer.app.session``) with
imgui and calls the session's actions; it keeps no state of its own beyond its widgets' (a path
being typed, an open file dialog). ``side.SidePanel`` stacks them in the side panel;
``lecture.draw_strip`` is lecture mode's narrow strip; ``overlays`` draws over the 3D view."""
