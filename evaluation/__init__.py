"""Evaluation of driving agents: run them, measure them, show the results.

Agents decide; this package measures them (``../shared/DESIGN.md``, "Where evaluation
lives"). It imports agents only through :mod:`sdc_agents.registry`, and neither ``sdc_gym``
nor ``agents`` imports it. ``evaluate.py`` is its command line; ``train.py`` uses its
atomic file writes.

Modules, from the episode up:

* :mod:`~sdc_evaluation.episodes`: one (agent, seed) episode: spec, trace, :func:`run_episode`;
* :mod:`~sdc_evaluation.incident_reports`: the seconds of history before each incident;
* :mod:`~sdc_evaluation.runner`: many episodes, in this process or a local process pool
  (the backend seam for other executors), with a progress bar;
* :mod:`~sdc_evaluation.statistics`: bootstrap intervals, IQM, P(improvement), Poisson rates;
* :mod:`~sdc_evaluation.summary`: per-agent rows and samples;
* :mod:`~sdc_evaluation.verdicts`: agent pairs compared, one line each;
* :mod:`~sdc_evaluation.analysis`: rows + comparisons for a run or runs side by side;
* :mod:`~sdc_evaluation.tables`: the 80-column tables (and the wide one);
* :mod:`~sdc_evaluation.files`: the CSV, JSON and NPZ files, atomically;
* :mod:`~sdc_evaluation.plots`, :mod:`~sdc_evaluation.profiles`,
  :mod:`~sdc_evaluation.incident_plots`: the PNG figures; :mod:`~sdc_evaluation.report`:
  the self-contained ``report.html``;
* :mod:`~sdc_evaluation.outputs`: everything a run writes; :mod:`~sdc_evaluation.run_folders`:
  timestamped run folders and ``results/latest``; :mod:`~sdc_evaluation.compare`: runs side
  by side.
"""
