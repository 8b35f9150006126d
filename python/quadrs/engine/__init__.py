"""The engine as the package calls it: the compiled handle of a scenario (``compiled``) and the
guarded calls into it (``calls``: argument ranges, memory budgets, Ctrl-C). The engine itself is
the Rust extension ``quadrs._core``."""
