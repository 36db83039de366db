"""Reports of recorded runs: one run -> ``report.md`` with figures; several runs -> a comparison.

Pure package (no rclpy): the time series come from :meth:`adcs_sim.app.analysis.RunData.from_bag`
(one streaming pass over the bag) and the numbers from :mod:`adcs_sim.app.analysis`. Figures are
drawn with :class:`matplotlib.figure.Figure` (no pyplot, no GUI backend) and saved as PNG and SVG.
One module per job:

* :mod:`.loading` — a bag -> a :class:`~.loading.Run` (one-line :class:`~.loading.BagError` for
  what is not a readable bag), where reports go, and the series derived from a run (controller
  status values, commanded torque, fault events, missing topics); no matplotlib;
* :mod:`.figures` — the figures of one run (:data:`~.figures.FIGURES`) and the drawing helpers;
* :mod:`.markdown` — value formatting, escaping and the meaning of each metric in the tables;
* :mod:`.single_run` — :func:`~.single_run.write_report`: ``report.md`` (how the bag was read —
  complete, or recovered from a truncated file and how many messages —, the topics it holds and
  the ones missing, fault events, the scenario as embedded in the bag, the metrics and the
  figures) and one ``<figure>.png`` and ``<figure>.svg`` per figure the bag has data for;
* :mod:`.comparison` — :func:`~.comparison.write_comparison`: ``comparison.csv`` and
  ``comparison.md`` (one column per run, rows of :func:`~.comparison.comparison_rows`), overlaid
  figures (one line per run) and, with published figures, a published-vs-ours table.

Every time axis carries a red dashed marker at each fault event: a status of level ERROR on the
``faults`` topic (``diagnostic_msgs/DiagnosticArray``) whose previous status of the same name was
not ERROR.
"""
