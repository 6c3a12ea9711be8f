"""The command line's names, which the window's messages name too: ``COMMANDS`` and
``HEADLESS_HINT`` (the commands that need no display, in one line); ``add_trust_option``, the
``--trust-twin PATH`` option of every command that opens materials."""

import argparse

COMMANDS = ("render", "reference", "compare", "bake", "plot", "models", "fit", "check", "handout")
HEADLESS_HINT = ("headless commands (no display needed): brdf-viewer render SCENE --out img.png | "
                 "brdf-viewer reference SCENE --spp 64 --out ref.png | brdf-viewer compare SCENE --spp 64 "
                 "--out folder | brdf-viewer bake SCENE --spp 256 | brdf-viewer plot MODEL --kind polar "
                 "--out plot.png | brdf-viewer fit FILE.binary --model MODEL | brdf-viewer models | "
                 "brdf-viewer check FILE.brdf | brdf-viewer handout FOLDER (SCENE: a "
                 ".toml file, a built-in name or lecture:N; see README)")


TRUST_HELP = ("run the numpy twin NAME.py of the .brdf files in this folder (and below), or of this file (repeatable; also "
              "$BRDF_VIEWER_TRUST_TWINS, paths joined by ':'); a twin is Python code and runs only when trusted "
              "so, never because a scene, a screenshot or a folder names it (the program's own viewer/brdfs is "
              "trusted)")


def add_trust_option(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """``--trust-twin PATH`` on a command that opens materials."""
    p.add_argument("--trust-twin", dest="trust_twin", action="append", default=[], metavar="PATH", help=TRUST_HELP)
    return p
