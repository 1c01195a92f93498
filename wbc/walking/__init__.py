"""wbc.walking."""
