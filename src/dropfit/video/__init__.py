"""The video path, one module per step of the data flow.

``decode`` (frames and their times from the file, rotation applied) → ``background`` (the scene
without the ball) → ``detect`` (the ball in one frame: colour, shape, size) → ``link`` (the ball
among things that move: the round blobs of many frames that fly on a parabola) → ``track`` (the ball
through the clip, kept only where it moves ballistically) → ``calibrate`` (pixels to metres and
frames to seconds). ``limits`` says when a tracked clip cannot give a meaningful number and
``overlay`` draws what was tracked. :func:`dropfit.videolog.trajectory_from_video` applies them
in order and returns the same trajectory as a height log.
"""
