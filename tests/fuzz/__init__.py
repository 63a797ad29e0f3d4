"""The fuzzing campaign kept as tests. Profiles (``HYPOTHESIS_PROFILE``):

- ``ci`` (default): a fixed seed (derandomized) and a small example budget, a minute or
  two on two cores;
- ``long``: random seeds and 50x the examples, for on-demand runs:
  ``HYPOTHESIS_PROFILE=long python -m pytest tests/fuzz``.
"""

import os

from hypothesis import HealthCheck, settings

_COMMON = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                      HealthCheck.data_too_large])
settings.register_profile("ci", max_examples=60, derandomize=True, **_COMMON)
settings.register_profile("long", max_examples=3000, **_COMMON)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


def scaled(n: int) -> int:
    """An example budget ``n`` for the ci profile, scaled with the loaded profile."""
    return max(1, n * settings.default.max_examples // 60)
