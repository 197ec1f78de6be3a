"""The baselines TL-AC is compared with, each an algorithm of the registry
(:func:`tlac.algorithms.get_algorithm`): DQN-TLQL and AC-Teach (:mod:`~tlac.baselines.dqn_tlql`,
:mod:`~tlac.baselines.ac_teach`, sharing :mod:`~tlac.baselines.off_policy`'s replay buffer, learn
loop and checkpoints), and SB3's PPO and A2C without teachers
(:mod:`~tlac.baselines.sb3_baselines`). docs/baselines/ describes them."""
