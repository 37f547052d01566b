"""The probe-set viewer: ``envcap view DIR`` serves a WebGL2 page on 127.0.0.1 that walks a probe
set's streets with objects shaded by the runtime GLSL (the WebGL2 target), one parallax method at
a time (docs/viewer.md).

* :mod:`envcap.viewer.site`: what the page reads besides the probe set's files (street uniforms
  from the manifest, the runtime GLSL for WebGL2, the evaluation report's plots);
* :mod:`envcap.viewer.crowd_site`: the crowd of ``envcap crowd`` in the street view (walkers
  posed in numpy, sent per frame as the crowd shader's textures);
* :mod:`envcap.viewer.server`: the HTTP server (``http.server``, loopback only);
* :mod:`envcap.viewer.browser`: headless Chromium over the DevTools protocol (tests, screenshots,
  the WebGL2 cost benchmark);
* ``envcap/viewer/web/``: the page (plain ES modules, raw WebGL2, no build step).
"""

from envcap.viewer.server import ViewerServer, serve
from envcap.viewer.site import WEB_DIR, ViewerSite

__all__ = ["WEB_DIR", "ViewerServer", "ViewerSite", "serve"]
