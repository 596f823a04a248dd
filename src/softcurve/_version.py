"""The package version, in one place (read by the facade, the CLI and sweep manifests)."""

__version__ = "0.3.0"
