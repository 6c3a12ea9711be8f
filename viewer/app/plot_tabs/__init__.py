"""The tabs of the window's "BRDF plots" panel (``viewer.app.plots_panel.PlotsPanel``), one
module each: ``polar``, ``lobe`` (3D lobe), ``albedo``, ``fresnel``, ``bouguer``, ``spectral``,
``sampling``, ``theta`` (BRDF Explorer's Theta H, Theta D and Theta V, and the settings the
slice tabs share), ``terms`` (a microfacet lobe's D, F, G), ``image_slice`` and ``check``; ``common`` holds what they share (the palette, the light's colour, small
drawing helpers). Each tab module has ``draw(panel, names, materials)``: it reads the panel's
settings (theta_i, phi, channel, log), its cached data (``panel.data``) and appends to
``panel.messages`` what the plot cannot show."""
