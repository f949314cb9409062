"""repertoire: a Drake framework for robots that reuse a repertoire of skills.

Subpackages (one per layer, data flows top to bottom):

- ``repertoire.models``   robot and world models (URDF/SDF) and ``ConfigureParser``
- ``repertoire.planning`` offline learning and planning -> artefacts
- ``repertoire.systems``  LeafSystems that execute artefacts online
- ``repertoire.diagrams`` builders returning named Diagrams, rendering, replay
- ``repertoire.studies``  Monte-Carlo study engine and the studies themselves
"""

from repertoire.errors import RepertoireError

__version__ = "0.1.0"
__all__ = ["RepertoireError", "__version__"]
