"""Training behind train.py: what is shared by its frameworks, and RLlib with Ray Tune.

``train.py`` parses the command line and resolves the run config (YAML, hyperparameters by
env id, overrides), then trains with stable-baselines3 itself or hands the run to
:mod:`~sdc_training.rllib_trainer` (``--framework rllib``) or :mod:`~sdc_training.tune_sweep`
(``--tune``). Modules:

* :mod:`~sdc_training.driving_metrics`: an episode's driving summary as TensorBoard scalars
  (``driving/``), the same for SB3 and RLlib;
* :mod:`~sdc_training.yaml_files`: run configs and sweep files read with clear errors;
* :mod:`~sdc_training.rllib_config`: an RLlib ``AlgorithmConfig`` from the run config
  (``configs/hyperparams/rllib_<algo>.yaml``), with clear errors for unknown keys;
* :mod:`~sdc_training.rllib_callbacks`: the RLlib callback that logs the driving metrics in
  the env runners;
* :mod:`~sdc_training.rllib_trainer`: an RLlib run with the run folder of an SB3 run
  (checkpoints, ``--resume``, evaluation on held-out seeds, ``best_model/``, TensorBoard);
* :mod:`~sdc_training.tune_sweep`: a Ray Tune sweep from a YAML search space (ASHA), its
  table of trials and its best checkpoint.

Ray is the optional extra ``ray`` (``pip install -e ".[ray]"``); this package imports it
only in the RLlib modules.
"""
