"""Grounding spoken words in images: the shapes-and-colours experiment of thesis 5.2–5.5.

:mod:`.dataset` makes the data, :mod:`.features` turns images and speech into vectors,
:mod:`.sparse` holds the paired and compositional sparse models, :mod:`.evaluate` the
retrieval and unseen-pair evaluations, :mod:`.model` a trained model with file-level queries.
"""

from artmotion.language.grounding.sparse import CompositionalSparse, PairedSparse, estimate_linking

__all__ = ["CompositionalSparse", "PairedSparse", "estimate_linking"]
