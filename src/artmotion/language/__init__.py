"""artmotion.language: say what happened (5.1) and let words drive vision (5.2–5.5).

:func:`artmotion.language.describe.describe` turns tracks, events and pose sequences into
subject–verb–adjective sentences; :mod:`artmotion.language.grounding` links spoken colour and
shape words to images with paired and compositional sparse models.
"""
