"""Material presets: name -> material table (``model`` plus parameters), usable in scene files
as ``preset = "gold"`` with any parameter overridden beside it."""

PRESETS: dict[str, dict] = {
    "white_lambert": {"model": "lambert", "albedo": [0.8, 0.8, 0.8]},
}
