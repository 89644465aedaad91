"""MCAP logs: recording every topic of a run (`recorder`), reading logs back into lotsen messages
(`reader`), replay on the bus (`replay`), export to tables (`export`), live view in Foxglove
(`live`), and the functions that attach these to a stack (`part`)."""

from lotsen.logs.reader import CorruptLogError, LogFileError, LogReader, TruncatedLogError, read_log
from lotsen.logs.recorder import McapRecorder, RecorderConfig, next_log_path

__all__ = ["CorruptLogError", "LogFileError", "LogReader", "TruncatedLogError", "read_log", "McapRecorder",
           "RecorderConfig", "next_log_path"]
