"""Shared test settings: hypothesis profiles.

* ``dev`` (the default on a workstation): random examples, a new draw every run (pass
  ``--hypothesis-seed=N`` to pytest to replay one), no deadlines (numba compiles once);
* ``ci`` (selected when the environment variable ``CI`` is ``true``, as CI services and
  ``.ci/run`` set it): the same with ``derandomize=True``, so a CI run draws the same
  examples every time and its result does not depend on luck, and no example database.

``HYPOTHESIS_PROFILE=dev|ci`` chooses a profile explicitly.
"""

import os

from hypothesis import HealthCheck, settings

settings.register_profile(
    "dev", deadline=None, max_examples=50, suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "ci", parent=settings.get_profile("dev"), derandomize=True, database=None,
    print_blob=True,
)
_in_ci = os.environ.get("CI", "").strip().lower() in ("true", "1", "yes")
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE") or ("ci" if _in_ci else "dev"))
