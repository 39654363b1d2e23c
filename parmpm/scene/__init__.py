"""Scenes: TOML in, validated and resolved scene out (schema, bodies, built-in scenes, agreement across ranks)."""
