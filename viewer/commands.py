"""The command line's names, which the window's messages name too: ``COMMANDS`` and
``HEADLESS_HINT`` (the commands that need no display, in one line)."""

COMMANDS = ("render", "reference", "compare", "bake", "plot", "models", "fit", "check")
HEADLESS_HINT = ("headless commands (no display needed): brdf-viewer render SCENE --out img.png | "
                 "brdf-viewer reference SCENE --spp 64 --out ref.png | brdf-viewer compare SCENE --spp 64 "
                 "--out folder | brdf-viewer bake SCENE --spp 256 | brdf-viewer plot MODEL --kind polar "
                 "--out plot.png | brdf-viewer fit FILE.binary --model MODEL | brdf-viewer models | "
                 "brdf-viewer check FILE.brdf (SCENE: a "
                 ".toml file, a built-in name or lecture:N; see README)")
