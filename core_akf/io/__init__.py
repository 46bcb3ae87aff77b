"""Measured data in: readers of data-acquisition formats (:mod:`~core_akf.io.readers`), units
converted to SI (:mod:`~core_akf.io.units`) and records of one or many files delivered in chunks
(:mod:`~core_akf.io.record`)."""
from .readers import Reader, Timing, formats, open_file, register_reader
from .record import Record, open_record, record_files
from .units import SI_UNITS, conversion

__all__ = ["Reader", "Record", "open_record", "SI_UNITS", "Timing", "conversion", "formats", "open_file", "record_files",
           "register_reader"]
