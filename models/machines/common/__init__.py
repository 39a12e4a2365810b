"""What every machine family shares: its result, units, buffer tables, pixel bus and
section bands.  Neutral: the families and ``rtl/`` may import it, it imports no family."""
