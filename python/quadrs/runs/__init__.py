"""Flights and batches: one flight (``flight``), Monte Carlo batches (``montecarlo``, their
result ``montecarlo_result``, the chunks they fly in ``chunk``, checkpoints ``store``, Dask
``distributed``), sweeps over a grid (``sweep``), turbulence alone (``gust``) and spectra
(``psd``)."""
