"""Shared test settings: a hypothesis profile without deadlines (numba compiles once)."""

from hypothesis import HealthCheck, settings

settings.register_profile(
    "penaltyrun", deadline=None, max_examples=50,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("penaltyrun")
