"""repertoire.diagrams: builders returning named Diagrams, rendering, replay."""
