"""repertoire.systems layer (see DESIGN.md)."""
