"""Brush-model reality generator (see README.md)."""
