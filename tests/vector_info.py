"""Comparing the infos of two vector environments (the native one against gymnasium's sync one)."""

from __future__ import annotations

import numpy as np


def same_info(native: dict, sync: dict) -> None:
    """Vector infos with the same keys, dtypes and values (floats to float32 rounding, batches differ)."""
    assert sorted(native) == sorted(sync)
    for key, expected in sync.items():
        got = native[key]
        if isinstance(expected, dict):
            same_info(got, expected)
        elif key == "final_obs":
            for a, b in zip(got, expected):
                assert (a is None and b is None) or np.allclose(a, b, atol=1e-6)
        else:
            assert got.dtype == expected.dtype and got.shape == expected.shape, key
            if np.issubdtype(expected.dtype, np.floating):
                # float32 rounding of energies, up to 1e-5 once a ratio is in percent
                np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-4, err_msg=key)
            else:
                np.testing.assert_array_equal(got, expected, err_msg=key)
