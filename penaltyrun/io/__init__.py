"""Results storage: one Parquet schema (:mod:`penaltyrun.io.schema`)."""

from penaltyrun.io.schema import (
    COLUMNS,
    RESULTS_FILE,
    SCHEMA,
    collect,
    decode_json,
    find_results,
    read_results,
    strict_json,
    to_table,
)

__all__ = ["COLUMNS", "RESULTS_FILE", "SCHEMA", "collect", "decode_json", "find_results",
           "read_results", "strict_json", "to_table"]
