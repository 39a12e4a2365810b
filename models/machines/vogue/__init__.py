"""VOGUE: modules casting whole host-defined rays, joined by a ring network."""
