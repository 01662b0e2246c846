"""Weather: EPW files read into the hourly weather channels W_k (:mod:`.epw`) and morphed copies (:mod:`.morph`)."""
