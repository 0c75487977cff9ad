"""The scene data set the games are played on: random table-top scenes seen by both simulated
robots' own pipelines (:mod:`.joint_scenes`), their records (:mod:`.records`), the contexts a
game draws from them (:mod:`.contexts`) and how far the two robots agree on what they see
(:mod:`.agreement`)."""
