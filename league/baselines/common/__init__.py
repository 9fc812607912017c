"""What the baselines really share, one module per concern (as ``stable_baselines3.common``):

- `off_policy`: the training loop of TD3, DDPG, DDPG with parameter noise, SAC and DSAC, and the
  `OffPolicyLearner` each of them provides;
- `args`: `CommonArgs` (the arguments every algorithm has), `option`, their checks, `TrainError`;
- `cars`: the environment wrapper, K cars collecting at once, each on its own tracks;
- `buffers`: the replay buffer of the off-policy algorithms;
- `networks`: layers, frozen observation statistics, the Polyak update, fused Adam;
- `seeding`: the one seeding block, and the global generators' states for checkpoints;
- `logger`: scalars to CSV (and TensorBoard);
- `evaluation`: `metrics_run` of the deterministic actor, and which evaluation is best;
- `run`: a training run's folder, progress bar, evaluations, checkpoints and summary;
- `export`: the deterministic actor to ONNX or TorchScript, checked against the torch actor;
- `plots`: the training curves.

Nothing algorithm-specific lives here: the networks, losses and updates are in one file per
algorithm (PPO's loop too: it is the one on-policy algorithm).
"""
