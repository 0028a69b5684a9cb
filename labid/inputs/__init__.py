"""labid/inputs."""
