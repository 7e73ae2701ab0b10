"""The reconstruction workbench: look at a reconstruction, correct it with keyframes,
re-solve from the current motion, keep the result (``pinrecon edit``).

* :class:`Session` - the state and every correction, no user interface (tested through
  its Python API);
* :mod:`.edits` - the geometry of the corrections (depth flips, spans, point fits);
* :func:`export_html` - a self-contained HTML player of a result (``pinrecon export --html``);
* :class:`Workbench` / :func:`serve` - the browser page (the ``edit`` extra: viser).
"""

from .edits import Segment, segments, skeleton_edges
from .html_export import export_html, html_player
from .session import Session, SolveReport

__all__ = ["Session", "SolveReport", "Segment", "segments", "skeleton_edges", "export_html", "html_player",
           "Workbench", "serve"]


def __getattr__(name):
    if name in ("Workbench", "serve"):
        from . import app

        return getattr(app, name)
    raise AttributeError(name)
