"""Sound of the bounces: impact times from a microphone, and from them flights and e.

The modules follow the data: :mod:`.decode` reads the sound (soundfile, or PyAV for compressed files
and a video's sound track), :mod:`.tables` reads tables of impact times (a CSV, a phyphox export),
:mod:`.onsets` finds and times the clicks, :mod:`.flights` turns impact times into flights, speeds,
rises and e with their covariance, and :mod:`.recording` carries them through dropfit's pipeline
(:mod:`dropfit.pipeline` measures and analyses a sound recording as it does a log or a video).
"""
