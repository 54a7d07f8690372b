"""The scipy reference is quiet: no RuntimeWarning from scipy's Radau reaches the caller."""

import warnings

from cosserat_channel.physics.reference import reference


def test_radau_reference_emits_no_runtime_warning():
    """At points where Radau's step predictor divides by a zero error norm (stability's series:
    eta = 1 at A = 1/3, N = 1 and eta = 10 at A = 2, N = 3), the reference answers silently."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        for eps, L, A, N in [(0.1, 10.0, 1 / 3, 1.0), (0.5, 20.0, 2.0, 3.0)]:
            out = reference(eps, L, 0.5, A, N, method="Radau", rtol=1e-12)
            assert out["status"] == "ok"
