-- A replay reads every tag's states in a time range (GET /api/v1/history without a tag).
CREATE INDEX locations_time_s ON locations (time_s);
