"""Evaluation of driving agents: run them, measure them, show the results.

Agents decide; this package measures them (``../shared/DESIGN.md``, "Where evaluation
lives"). It imports agents only through :mod:`agents.registry`, and neither ``sdc_gym``
nor ``agents`` imports it. ``evaluate.py`` is its command line; ``train.py`` uses its
atomic file writes.

Modules, from the episode up:

* :mod:`~evaluation.episodes`: one (agent, seed) episode: spec, trace, :func:`run_episode`;
* :mod:`~evaluation.incident_reports`: the seconds of history before each incident;
* :mod:`~evaluation.runner`: many episodes, in this process or a local process pool
  (the backend seam for other executors), with a progress bar;
* :mod:`~evaluation.statistics`: bootstrap intervals, IQM, P(improvement), Poisson rates;
* :mod:`~evaluation.summary`: per-agent rows and samples;
* :mod:`~evaluation.verdicts`: agent pairs compared, one line each;
* :mod:`~evaluation.analysis`: rows + comparisons for a run or runs side by side;
* :mod:`~evaluation.tables`: the 80-column tables (and the wide one);
* :mod:`~evaluation.files`: the CSV, JSON and NPZ files, atomically;
* :mod:`~evaluation.plots`, :mod:`~evaluation.profiles`, :mod:`~evaluation.incident_plots`:
  the PNG figures; :mod:`~evaluation.report`: the self-contained ``report.html``;
* :mod:`~evaluation.outputs`: everything a run writes; :mod:`~evaluation.run_folders`:
  timestamped run folders and ``results/latest``; :mod:`~evaluation.compare`: runs side
  by side.
"""
