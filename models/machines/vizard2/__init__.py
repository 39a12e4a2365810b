"""VIZARD II: ray-order cycle machine, block cache, configuration, transaction model and
``vizard2.toml``."""
