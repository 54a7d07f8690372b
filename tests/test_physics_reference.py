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


def test_status_only_gives_the_full_reference_status():
    """Stage 1 alone decides the status: the same as the full reference's, on both sides of the
    README point's edge (eta_max = 3.30886) and at a point without an edge."""
    from cosserat_channel.physics.reference import reference

    for eps in (0.2, 0.3308, 0.3310):
        full = reference(eps, 10.0, 0.5, 1 / 3, 1.0)
        quick = reference(eps, 10.0, 0.5, 1 / 3, 1.0, status_only=True)
        assert quick["status"] == full["status"] and "Delta" not in quick
    assert {reference(e, 10.0, 0.5, 1 / 3, 1.0, status_only=True)["status"]
            for e in (0.2, 0.3310)} == {"ok", "eps_too_large_path"}
