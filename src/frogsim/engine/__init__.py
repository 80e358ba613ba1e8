"""Engines: the pneumatic model alone (prescribed muscle lengths) and, later, coupled bodies."""
