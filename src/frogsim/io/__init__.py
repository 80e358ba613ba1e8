"""Edges of frogsim: scenario files in, result files out. Units live here and nowhere deeper."""
