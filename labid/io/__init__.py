"""Recordings in, results out, and sensor calibration (issue 16).

``readers`` (TDMS by npTDMS, UFF58 by pyuff, WAV by scipy.io.wavfile, MAT by scipy.io,
CSV by numpy) -> ``importers.import_records`` (``labid import``: files into a run file
under a rig file); ``exporters`` (``labid export``: UFF58 FRFs and time data, UFF55 modes,
UFF15 nodes by pyuff; CSV tables of features, constants and diagnosis); ``calibration``
(the rig's calibration sheet, TEDS, the per-shot record, overdue warnings); ``units``.
Front-ends reach them through ``labid.services``.
"""
