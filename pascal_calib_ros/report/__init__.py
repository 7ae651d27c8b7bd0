"""The report a person reads: its numbers (``report.json``, :mod:`.numbers`), its pages
(``report.pdf`` and ``report.png``, :mod:`.pages`) and the words of every summary (:mod:`.text`)."""

from .numbers import ReportData, report_data, report_numbers
from .pages import PAGES, ReportFiles, write_report
from .stereo import write_stereo_report
from .text import format_summary, hand_eye_summary, projection_line, summary_line

__all__ = ["PAGES", "ReportData", "ReportFiles", "format_summary", "hand_eye_summary", "projection_line", "report_data",
           "report_numbers", "summary_line", "write_report", "write_stereo_report"]
