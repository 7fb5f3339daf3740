"""What both nodes' ROS shells and the tools share (the simulator's and the autopilot's packages
import it; it imports neither): sim-time stamps, and the flight's span protocol."""
