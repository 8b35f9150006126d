"""What people read, made from frames (never from a run): the paper's Table 3 as text and
Markdown (``table3``), the notebook display (``html``), units and labels as shown
(``labels``), and text safe for a terminal with its progress bar (``terminal``). Below the
results so that a result can show itself (``_repr_html_``)."""
