"""sensoropt: GA sensor placement (in development)."""
