"""repertoire.studies layer (see DESIGN.md)."""
