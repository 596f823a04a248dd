"""Identification from measurements: ``experiments`` (loading, units), ``maps`` (what
sensors measure, what inputs do) and ``fits`` (stiffness, trajectory and equilibrium
fits, their reports)."""
