"""Placeholder: filled in by the fish_swarm family implementation."""
