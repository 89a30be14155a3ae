"""Backends: loops that apply the physics functions over all bonds, contacts, particles."""
