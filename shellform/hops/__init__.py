"""shellform as Grasshopper components: a server for the Hops component.

``shellform serve`` starts :class:`~shellform.hops.server.HopsServer` on
127.0.0.1; Hops components in Grasshopper point at
``http://127.0.0.1:<port>/<Component>`` (docs/grasshopper.md). The components
(:mod:`shellform.hops.components`) build scenes from their inputs and run
them through :func:`shellform.api.run`, as the command line does.
"""

from .components import COMPONENTS
from .server import HopsApp, HopsServer, start

__all__ = ["COMPONENTS", "HopsApp", "HopsServer", "start"]
