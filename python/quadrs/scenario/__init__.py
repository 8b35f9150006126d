"""What to fly: the validated scenario (``scenario``: presets, TOML, overrides; made of
``keys``, ``tables``, ``preset_files`` and ``toml_layout``), its uncertain parameters
(``dispersion``), routes (``route``), the unit of every key (``units``) and the plausibility
checks (``plausibility``)."""
