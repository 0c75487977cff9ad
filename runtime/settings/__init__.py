"""The files a user edits, read into typed settings: robot platform profiles,
experiments and scenes."""
