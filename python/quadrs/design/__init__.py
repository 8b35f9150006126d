"""The design loop on Monte Carlo batches: tuning and calibration (``optimize``, with
``constraints``), Sobol' sensitivity (``sensitivity``) and the mission report
(``mission``: will the parcel survive this route?, its numbers in ``mission_tables`` and its
text in ``mission_text``)."""
