"""What to fly: the validated scenario (``scenario``: presets, TOML, overrides), its uncertain
parameters (``dispersion``), routes (``route``), the unit of every key (``units``) and the
plausibility checks (``plausibility``)."""
