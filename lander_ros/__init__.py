"""What both nodes' ROS shells and the tools share (the simulator's and the autopilot's shells
import it; it imports neither, only the plain-Python core): sim-time stamps, parameters, output
delivery, and the flight's span protocol."""
