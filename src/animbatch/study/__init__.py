"""The work-precision study: what accuracy costs in time, per integrator, for one scene (``animbatch study``)."""

from animbatch.study.report import StudyReport, table, write_outputs
from animbatch.study.study import TARGETS, StudyResult, StudyRow, run_study

__all__ = ["TARGETS", "StudyReport", "StudyResult", "StudyRow", "run_study", "table", "write_outputs"]
