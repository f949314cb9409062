"""repertoire.planning layer (see DESIGN.md)."""
