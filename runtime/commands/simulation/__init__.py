"""The commands of the simulated world: a robot's camera rendered, the demo of two robots, scene
files drawn at random, scene data sets and the language games played on them."""
