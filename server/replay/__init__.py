"""Replaying a recorded session (``teleprog replay FILE``): the timeline of what the console
showed (``timeline``), each submitted range's plan against the robot's reported motion
(``comparison``), the playhead (``player``) and the read-only app (``app``); the page is
``webui.replay``."""
