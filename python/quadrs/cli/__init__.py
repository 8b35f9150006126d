"""``quadrs``, the command line: the parser and most commands (``main``), the design, mission
and rare-event commands (``design``, ``mission``, ``rare``), what they share (``common``), how
outputs are saved (``outputs``) and the cost said before a long run (``cost``)."""
