"""The paper's sweep grids, importable without the plotting stack (the CLI's help shows them)."""

#: Natural frequencies (Hz) of the Fig. 13/14 sweep.
FREQUENCIES: tuple[float, ...] = (0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)
#: Payload masses (kg) of Fig. 16: 1 %, 10 % and 20 % of the vehicle, as in the paper.
MASSES: tuple[float, ...] = (0.022, 0.22, 0.44)
