"""Run outputs: ``stats.json``, images, CSVs and (later) human reports."""

from hwsim.report.output import STATS_SCHEMA, stats_dict, write_render

__all__ = ["STATS_SCHEMA", "stats_dict", "write_render"]
