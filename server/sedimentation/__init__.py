"""The particle-sedimentation demo (``teleprog up --sedimentation``, thesis chapter 5), apart from
the robot console: ``runner`` steps the scene and times the detector, ``app`` serves it (its view
is ``webui.sedimentation``)."""
