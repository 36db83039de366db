"""Monte Carlo campaigns: the campaign file, its draws and checks, adcs-montecarlo and adcs-tune-gsmn."""
