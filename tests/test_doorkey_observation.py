"""The DoorKey env builds its full-grid observation itself (for speed); it must match what
MiniGrid's own FullyObsWrapper produces, step for step."""

from __future__ import annotations

import numpy as np

from tlac.domains.doorkey.env import make_doorkey_env, make_reference_doorkey_env


def test_fast_full_observation_equals_minigrids_fully_obs_wrapper():
    fast, reference = make_doorkey_env(), make_reference_doorkey_env()
    rng = np.random.default_rng(0)
    steps = 0
    for seed in range(12):
        a, _ = fast.reset(seed=seed)
        b, _ = reference.reset(seed=seed)
        np.testing.assert_array_equal(a, b)
        for _ in range(300):
            action = int(rng.integers(6))
            out_a, out_b = fast.step(action), reference.step(action)
            np.testing.assert_array_equal(out_a[0], out_b[0])
            assert out_a[1:4] == out_b[1:4]
            steps += 1
            if out_a[2] or out_a[3]:
                break
    assert steps > 1000
