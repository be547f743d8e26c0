"""The seed paper's tables as data and our numbers beside every number it prints."""
