"""The web handout (``brdf-viewer handout OUT``): a static folder with one page per lecture step
and an index, which opens from disk or any static host with no server and no network.

``pages`` writes the HTML and the style sheet and runs the build (``build_handout``), ``assets``
makes each step's pictures and numbers (raster, reference from the reference cache, difference
map, the step's plots with their JSON, the thumbnail), ``live`` writes the live WebGL2 view of a
step (its canvas, sliders, scripts and shaders)."""
