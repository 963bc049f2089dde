"""The components the Hops server offers: inputs to a scene, a run's files to outputs.

Every component turns its inputs into a scene (a dictionary in the scene
format), which :func:`shellform.scene.parse_scene` checks exactly as it checks
a scene file, and runs it with :func:`shellform.api.run`; its outputs are read
from the files the run wrote. An input that fills a scene key is refused with
the scene's own message about that key. No input names a file: the scenes
built here never read or write a path a client gave.

=============  ======================================================================
component      analysis
=============  ======================================================================
FormFind       ``mra``: a hanging net on a planform or a given mesh, relaxed and inverted
Lengths        ``mra`` with ``[analysis.lengths]``: rope lengths, classes, conformity
Gridshell      ``form_and_buckle``: rods on the found form, traced to buckling; or
               ``continuation`` of rods along given lines
Trace          ``continuation``: a bar or rope structure from lines
=============  ======================================================================
"""

from .component import Component
from .form_components import FORM_FIND, GRIDSHELL, LENGTHS
from .trace import TRACE

#: the components by name
COMPONENTS: dict[str, Component] = {c.name: c for c in (FORM_FIND, LENGTHS, GRIDSHELL, TRACE)}
