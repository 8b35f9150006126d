"""Statistics of runs tables, numbers only: the summary's means and intervals (``summary``),
exceedance probabilities and tail quantiles (``risk``), and the same tables per group of runs
(``groups``, inherited by every result with a ``runs`` table)."""
