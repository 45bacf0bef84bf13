"""Readers of the files zone publishers issue: each turns bytes into ParsedZones or
refuses the whole file with a ZoneFileError naming the problem (formats/common.py)."""
