"""Rig presets (TOML files), shipped as the package data ``rigsim.rigs``."""
