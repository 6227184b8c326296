"""ncopt: rewrite the S and F words of 3-axis finishing programs so the real
cutting speed and feed per tooth stay at their targets within what the spindle can do."""

__version__ = "0.1.0"
DISTRIBUTION = "ncopt-cnc"  # the name pip knows this project by ("ncopt" is another one)
