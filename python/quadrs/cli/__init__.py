"""``quadrs``, the command line: the top parser and the dispatch (``main``); one module per
command (``run``, ``mc``, ``sweep``, ``report``, ``paper``, ``stability``, ``sensitivity``,
``scenario``, ``design`` for tune and linearize, ``rare``, ``mission``); what they share: the
exit statuses and the options several take, each declared once (``common``), the scenario the
options give (``scenario_args``), the tables and figures of batches (``tables``,
``figures``), how outputs are saved (``outputs``) and the cost said before a long run
(``cost``)."""
