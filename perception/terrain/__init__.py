"""Terrain from depth images: planes, plane tracking, terrain description, footprints."""
