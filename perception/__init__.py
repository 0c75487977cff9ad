"""Perception: background model, foreground and motion, regions, colour-model splitting, Kalman
object anchors, sensory experiences and marker landmarks (chapter 5.2-5.3).

Data flows one way: frame -> percepts -> anchors -> sensory experiences.
"""
