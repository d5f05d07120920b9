"""Where frames come from (no Qt): the Source interface, playback, live boards, protocol, devices."""
