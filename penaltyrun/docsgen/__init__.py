"""Documentation machinery: reference pages generated from the code, results pages and the
README's answer table rendered from committed study data, and the study runner.

* :mod:`.reference` builds the reference pages (config keys, exit codes, Parquet schema,
  problem protocol) from the settings dataclasses, the problems' ``Params``, the YAML under
  ``penaltyrun/conf``, :data:`penaltyrun.cli.EXIT_CODES`, :mod:`penaltyrun.io.schema` and
  :mod:`penaltyrun.problems.base`; :mod:`.mkdocs_hook` hands them to MkDocs at build time.
* :mod:`.results` renders ``studies/templates/*.md`` (Jinja) against
  ``studies/*/results.parquet`` and the tables written beside it, and checks that the
  committed pages equal a fresh rendering (``make check-docs``).
* :mod:`.explanation` renders ``studies/templates/explanation/*.md`` into
  ``docs/explanation`` and draws their figures (:mod:`.fullmatrix`, :mod:`.fullmatrix_plots`:
  what a full matrix does, from the attitude study's data).
* :mod:`.studies` runs a study's commands (resumable), merges its Parquet and writes its
  tables (``make study-<name>``).

This is the top layer: it may import every other layer; nothing imports it.
"""
