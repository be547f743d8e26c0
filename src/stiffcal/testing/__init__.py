"""Test and benchmark support, never imported by production code: the truth simulator of lab logs, slow reference
solvers, the rate matrix and the maps' baseline."""
