"""From a frame to percepts (§4.1-4.2): the background model and the foreground, its connected
regions, their split with the anchors' colour models, and the percepts that feed the anchors."""
