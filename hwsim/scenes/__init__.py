"""Built-in scenes, one TOML file each (listed by ``hwsim scenes``)."""
