"""The VolumePro 500 (vg500) in RTL: its SDRAM controller first (issue 35)."""
