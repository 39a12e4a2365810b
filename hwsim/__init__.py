"""hwsim: a cycle-level simulator of Cube-4 / VolumePro-style volume-rendering hardware."""

__version__ = "0.1.0"
