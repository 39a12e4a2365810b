"""What a render is asked to do: the scene and its parts, the transfer function, the
architecture file with its published figures, and the machines' declared features."""
