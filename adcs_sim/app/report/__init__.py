"""Reports of recorded runs: one run -> ``report.md`` with figures; several runs -> a comparison.

Pure package (no rclpy): the time series come from :meth:`adcs_sim.app.analysis.metrics.RunData.from_bag`
(one streaming pass over the bag) and the numbers from :mod:`adcs_sim.app.analysis.metrics`; a long run
(more state samples than :data:`.envelope.MAX_POINTS`) is streamed instead (:mod:`.long_run`: two
passes, only the samples its figures draw kept, the same report byte for byte). Figures are
drawn with :class:`matplotlib.figure.Figure` (no pyplot, no GUI backend) and saved as PNG and SVG.
One module per job:

* :mod:`.long_run` — a long run's report within a bounded memory (issue #18: a day at 10 Hz);
  :mod:`.envelope` — long series drawn from their envelope, built whole or chunk by chunk;
* :mod:`.loading` — a bag -> a :class:`~.loading.Run` (one-line :class:`~.loading.BagError` for
  what is not a readable bag), where reports go, and the series derived from a run (controller
  status values, commanded torque, fault events, missing topics); no matplotlib;
* :mod:`.kinds` — what kind of run a bag holds (regulation, tracking, spin, pointing, from the
  controller family), the reference its controller follows and the run's phases; no matplotlib;
* :mod:`.lead` — each kind's own metrics (unit, meaning) and the paper's values beside ours
  (``docs/seed00X/paper.yaml``); no matplotlib;
* :mod:`.kind_figures` — the figures each kind leads with (:data:`~.kind_figures.LEAD_FIGURES`);
* :mod:`.figures` — the generic figures of one run (:data:`~.figures.FIGURES`) and the drawing helpers;
* :mod:`.status_figure` — the controller-status figure (grouped, with units);
* :mod:`.markdown` — value formatting, escaping and the meaning of each metric in the tables;
* :mod:`.single_run` — :func:`~.single_run.write_report`: ``report.md`` (how the bag was read —
  complete, or recovered from a truncated file and how many messages —, what kind of run it is
  with that kind's quantities and figures first, the sections other modules register
  (:func:`~.single_run.register_section`), the topics it holds and
  the ones missing, fault events, the scenario as embedded in the bag, the metrics and the
  figures) and one ``<figure>.png`` and ``<figure>.svg`` per figure the bag has data for;
* :mod:`.comparison` — :func:`~.comparison.write_comparison`: ``comparison.csv`` and
  ``comparison.md`` (one column per run, rows of :func:`~.comparison.comparison_rows`), overlaid
  figures (one line per run) and, with published figures, a published-vs-ours table.

Every time axis carries a red dashed marker at each fault event: a status of level ERROR on the
``faults`` topic (``diagnostic_msgs/DiagnosticArray``) whose previous status of the same name was
not ERROR.
"""
