"""Readers and writers: part files in, result files out."""
