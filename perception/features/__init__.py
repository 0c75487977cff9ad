"""Sensory experiences (chapter 5.2.3): the features of each anchor's object, the upright solid
fitted to its box that measures them, their scaling, and which anchors are agents.

The records a user of the sensory experiences meets are importable from here:
:class:`SensoryExperience`, :func:`sensory_experience` and :class:`SensoryMemory` (of
:mod:`.experience`).
"""

from percept.perception.features.experience import (
    SensoryExperience,
    SensoryMemory,
    sensory_experience,
)

__all__ = ["SensoryExperience", "SensoryMemory", "sensory_experience"]
