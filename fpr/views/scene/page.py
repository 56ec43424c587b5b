"""A recorded meshcat scene (:class:`SceneView`) and its standalone page.

The scene is recorded as meshcat commands (the dictionaries meshcat's Python side sends to its
viewer) through a ``meshcat.Visualizer`` whose window (:class:`_Recorder`) records instead of sending:
no server, no process. :attr:`SceneView.html` replays them in a standalone page: meshcat's viewer
script from the installed package inline, then the commands (msgpack, base64) decoded and handed to
the viewer. The page loads nothing else (its content security policy forbids it): it opens from a
file, offline, and inside a Jupyter output (:meth:`SceneView._repr_html_`, an ``<iframe srcdoc>``).
:meth:`SceneView.serve` sends the same commands to a live meshcat server.
"""

from __future__ import annotations

import base64
import contextlib
import html as html_lib
import io
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fpr.model.errors import FprError
from fpr.views.scene.geometry import _meshcat, _read_text

logger = logging.getLogger(__name__)

ROOT = "/meshcat"
"""Where meshcat puts the scene; :class:`SceneView` accepts paths relative to it."""


class _Recorder:
    """A meshcat window that keeps the commands instead of sending them to a server."""

    def __init__(self):
        self.commands: list[dict] = []

    def send(self, command) -> None:
        self.commands.append(command.lower())


class _Lowered:
    """A command already in meshcat's format, for ``window.send``."""

    def __init__(self, data: dict):
        self.data = data

    def lower(self) -> dict:
        return self.data


@dataclass(eq=False)
class SceneView:
    """A recorded meshcat scene: shown inline by Jupyter, written as a page, or sent to a server.

    Attributes:
        commands: the meshcat commands in order (``set_object``, ``set_transform``, ``set_property``,
            ``set_animation`` dictionaries, as meshcat sends them to its viewer).
        title: the page's title.
        duration: length of the animation [s]; None for a static robot.
        fps: key frames per second of the animation [1/s].
        thrust_scale: length of the thrust arrows per newton [m/N].
        legend: lines of text drawn over the page.
        camera: (eye, target), where the page's camera starts and what it looks at (world) [m].
    """

    commands: list
    title: str
    duration: float | None
    fps: float
    thrust_scale: float
    legend: tuple = ()
    camera: tuple | None = None
    _html: str | None = field(default=None, repr=False)

    @staticmethod
    def _full(path: str) -> str:
        return path if path.startswith("/") else f"{ROOT}/{path}"

    @property
    def paths(self) -> list[str]:
        """Every node path that receives a command, in order of first appearance."""
        return list(dict.fromkeys(c["path"] for c in self.commands if c.get("path")))

    def object(self, path: str) -> dict:
        """The three.js object set at ``path`` (relative to /meshcat, or absolute)."""
        full = self._full(path)
        for command in reversed(self.commands):
            if command["type"] == "set_object" and command["path"] == full:
                return command["object"]
        raise KeyError(f"no object at {full!r}")

    def transform(self, path: str) -> np.ndarray:
        """The 4x4 transform set at ``path`` (for an animated node: its pose at t = 0)."""
        full = self._full(path)
        for command in reversed(self.commands):
            if command["type"] == "set_transform" and command["path"] == full:
                return np.array(command["matrix"], dtype=float).reshape(4, 4).T  # three.js: column-major
        raise KeyError(f"no transform at {full!r}")

    def track(self, path: str, name: str) -> tuple[np.ndarray, np.ndarray]:
        """An animation track of ``path``: (times [s] (K,), values (K, 3) or (K, 4)).

        Args:
            path: node path (relative to /meshcat, or absolute).
            name: "position" [m], "quaternion" (x, y, z, w) or "scale".
        """
        full = self._full(path)
        for command in self.commands:
            for animation in command.get("animations", ()):
                if animation["path"] != full:
                    continue
                clip = animation["clip"]
                for track in clip["tracks"]:
                    if track["name"] == "." + name:
                        keys = track["keys"]
                        return (np.array([k["time"] for k in keys], dtype=float) / clip["fps"],
                                np.array([k["value"] for k in keys], dtype=float))
        raise KeyError(f"no {name!r} track at {full!r}")

    @property
    def html(self) -> str:
        """The standalone page (viewer script and scene inline; it requests nothing else)."""
        if self._html is None:
            self._html = _page(self)
        return self._html

    def write(self, path) -> Path:
        """Write :attr:`html` to ``path`` (a folder gets ``scene.html``); returns the file written."""
        path = Path(path)
        if path.is_dir():
            path = path / "scene.html"
        path.write_text(self.html, encoding="utf-8")
        logger.info("wrote %s", path)
        return path

    def __repr__(self) -> str:
        """A short summary (the commands hold the meshes: the generated repr ran to megabytes in a notebook)."""
        animation = "a still robot" if self.duration is None else f"{self.duration:g} s at {self.fps:g} fps"
        return f"SceneView({self.title!r}, {len(self.commands)} commands, {len(self.paths)} nodes, {animation})"

    def _repr_html_(self) -> str:
        """Jupyter: the page in an ``<iframe srcdoc>``; needs no server, stays in saved notebooks."""
        return (f'<iframe srcdoc="{html_lib.escape(self.html, quote=True)}" '
                f'title="{html_lib.escape(self.title)}" style="width: 100%; height: 520px; border: none" '
                'allowfullscreen></iframe>')

    def send(self, visualizer) -> None:
        """Replay the commands into a ``meshcat.Visualizer`` (a live server)."""
        for command in self.commands:
            visualizer.window.send(_Lowered(command))

    def serve(self, zmq_url: str | None = None):
        """Send the scene to a live meshcat server; returns the ``meshcat.Visualizer`` (``.url()``).

        Args:
            zmq_url: a running server (``meshcat-server``); default: start one, a subprocess that
                meshcat stops when Python exits. Its camera looks at the world origin (the
                standalone page aims at the workspace).
        """
        meshcat = _meshcat()
        with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints the URL; the caller decides
            visualizer = meshcat.Visualizer(zmq_url=zmq_url)
        logger.info("meshcat server at %s", visualizer.url())
        self.send(visualizer)
        return visualizer


_CSP = ("default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src data: blob:; "
        "media-src data: blob:; font-src data:; connect-src data: blob:; worker-src blob:")


def _viewer_script() -> str:
    """meshcat's viewer (three.js, msgpack decoding, controls), from the installed package."""
    path = Path(_meshcat().__file__).parent / "viewer" / "dist" / "main.min.js"
    if not path.is_file():
        raise FprError(f"meshcat's viewer script {path} is missing: reinstall meshcat (pip install meshcat)")
    return _read_text(str(path)).replace("</script", "<\\/script")


def _page(scene: SceneView) -> str:
    """The standalone page: the viewer script, then the commands replayed into a viewer."""
    import umsgpack

    commands = ",\n".join(f'"{base64.b64encode(umsgpack.packb(c)).decode("ascii")}"' for c in scene.commands)
    legend = "".join(f"<div>{html_lib.escape(line)}</div>" for line in scene.legend)
    eye, target = ((0.0, 0.0, 0.0),) * 2 if scene.camera is None else scene.camera
    # three.js' frame of meshcat's camera is y up: the world's (x, y, z) is (x, z, -y) there
    eye, target = (", ".join(f"{float(x):.6g}" for x in (v[0], v[2], -v[1])) for v in (eye, target))
    aim = "" if scene.camera is None else f"""
  viewer.camera.position.set({eye});
  viewer.controls.target.set({target});
  viewer.controls.update();"""
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="{_CSP}">
<title>{html_lib.escape(scene.title)}</title>
<style>
  body {{ margin: 0; }}
  #meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
  #fpr-legend {{ position: absolute; left: 8px; top: 8px; padding: 4px 8px; pointer-events: none;
    font: 12px sans-serif; color: #222; background: rgba(255, 255, 255, 0.7); border-radius: 4px; }}
  #fpr-legend b {{ font-size: 13px; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="fpr-legend"><b>{html_lib.escape(scene.title)}</b>{legend}</div>
<script>
{_viewer_script()}
</script>
<script>
(function () {{
  var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
  window.viewer = viewer;
  var commands = [
{commands}
  ];
  for (var i = 0; i < commands.length; i++) {{
    var text = atob(commands[i]);
    var bytes = new Uint8Array(text.length);
    for (var k = 0; k < text.length; k++) {{ bytes[k] = text.charCodeAt(k); }}
    viewer.handle_command_bytearray(bytes);
  }}{aim}
  viewer.set_dirty();
}})();
</script>
</body>
</html>
"""
