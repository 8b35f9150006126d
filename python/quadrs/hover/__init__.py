"""The closed loop linearised at hover: its poles and verdict (``stability``) and its
state-space model (``linear``)."""
