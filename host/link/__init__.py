"""The serial side: the logger link over pyserial, the memory dump, and the pyserial URL transports."""
