"""The issue's three scans of the reference rig, as `specula synth-samples` flags by light count: 165 lights at 1
degree steps (the default), 40 at 4 degree steps and 10 at 16 degree steps, each spanning the arc."""
LIGHTS = {"165": [], "40": ["--lights", "40", "--light-step", "4"], "10": ["--lights", "10", "--light-step", "16"]}
