"""The ncopt command: a thin layer over the library."""
