"""impactloc: impact localisation by SE/AD role search (in development)."""
