"""The paper in one call (``pipeline``) and its sweep grids (``grid``, light enough for the
command line's help)."""
