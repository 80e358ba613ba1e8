"""Result files: summaries, CSV tables and figures of runs (written atomically)."""
