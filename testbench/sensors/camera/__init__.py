"""Camera model and renderer: what an onboard camera sees of a mapped world.

Public API: `render` (pure renderer), `RenderOptions`, `RenderedFrame`, `VehicleAppearance`,
`VehicleTruth`, `project_points`, and the in-the-loop sensor `CameraSensor` (registered as
sensor type "camera") with its `CameraFrame` message, `CameraWorld` protocol and
`save_frame_png`.
"""

from testbench.sensors.camera.lens import project_points
from testbench.sensors.camera.render import render
from testbench.sensors.camera.sensor import CameraFrame, CameraSensor, CameraWorld, save_frame_png
from testbench.sensors.camera.types import RenderedFrame, RenderOptions, VehicleAppearance, VehicleTruth

__all__ = [
    "CameraFrame", "CameraSensor", "CameraWorld", "RenderOptions", "RenderedFrame", "VehicleAppearance",
    "VehicleTruth", "project_points", "render", "save_frame_png",
]
