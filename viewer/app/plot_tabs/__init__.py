"""The tabs of the window's "BRDF plots" panel (``viewer.app.plots_panel.PlotsPanel``), one
module each: ``polar``, ``lobe`` (3D lobe), ``albedo``, ``fresnel``, ``bouguer``, ``spectral``
and ``sampling``; ``common`` holds what they share (the palette, the light's colour, small
drawing helpers). Each tab module has ``draw(panel, names, materials)``: it reads the panel's
settings (theta_i, phi, channel, log), its cached data (``panel.data``) and appends to
``panel.messages`` what the plot cannot show."""
