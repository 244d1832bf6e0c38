"""Robot descriptions of the source papers (one TOML file each, plus an optional module of extras)."""
