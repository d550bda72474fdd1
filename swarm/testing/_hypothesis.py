"""Imported first by the modules of :mod:`swarm.testing` that need Hypothesis (strategies and
the state machine), so that without it they fail with one clear line. The checkers
(:mod:`swarm.testing.invariants`, :mod:`swarm.testing.liveness`) need nothing beyond the
simulator: ``swarm paper`` judges runs with them."""

try:
    import hypothesis  # noqa: F401
except ImportError as exc:  # pragma: no cover - depends on the environment
    raise ImportError(
        "swarm.testing's strategies and state machine need Hypothesis: install the testing extra, "
        "pip install 'uav-swarm-sim[testing]' (swarm.testing.invariants needs nothing more)"
    ) from exc
