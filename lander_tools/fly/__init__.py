"""``lander fly``: start the simulator and the autopilot, fly, record, stop cleanly.

The launcher for machines without ``ros2 launch`` (ROS 2 from PyPI); on a full
install ``ros2 launch mars_lander fly.launch.py`` starts the same two nodes
(``launch/fly.launch.py``). Run (project venv)::

    ./dev fly hover --duration 60 --speed 0 --record out/hover
    ./dev fly free-spin                      # no autopilot in the scene: the sim alone
    ./dev fly 7 --controller altitude-p --params my.yaml --compose

What it does:

Before anything starts, the scene, controller and flight names and the ``--params`` file are
checked (:func:`~lander_tools.fly.checks.check_plan`: one line naming what is wrong, with the
closest name). Then :func:`~lander_tools.fly.phases.fly` runs these phases, top-down, each a
function of its own in :mod:`lander_tools.fly.phases`:

1. :func:`start_nodes`: one ROS parameters file per node (``lander_sim``, ``autopilot``) from
   the user's ``--params`` sections and the flight's settings; the sim node (paused, with the
   flight's end as its ``end_time``/``end_on``) and, when the scene or ``--controller`` names a
   controller, the autopilot node, as processes (or one with ``--compose``), their output
   forwarded under a ``[sim]`` / ``[autopilot]`` prefix; the recorder (``--record``) in this
   process (:class:`~lander_tools.recorder.Recorder`, held by the launcher's own node,
   :class:`~lander_tools.fly.supervisor.Supervisor`);
2. :func:`wait_until_matched`: every subscriber the flight needs (recorder on every recorded
   topic, autopilot, this launcher) is matched by the publishers' writers, asked of the sim
   (``/lander/subscribers``) and of the recorder's readers;
3. :func:`reset_flight`: reset the sim, so state 1 at t = 0 reaches everyone (and, in lockstep,
   the autopilot has answered it);
4. :func:`run_to_end`: resume and apply the flight's timeline (demand steps, wind, controller
   swaps, throttle overrides) at the first control instant at or after each time, exactly in
   sim time at any speed (with an autopilot the sim pauses there, ``pause_at``, while the
   action is put in force: :mod:`lander_tools.fly.timeline`), until the sim announces ``FLIGHT_ENDED``: the
   sim itself stops at the end instant (time limit, landing or crash), so the flight's span does
   not depend on how fast this process reacts (docs/sim_node.md, "A flight's span");
5. :func:`stop_nodes`: wait until the recorder holds every message the sim counted, then stop
   the nodes, autopilot first (SIGINT, SIGTERM, SIGKILL after a grace period);
6. :func:`close_and_check_bag`: close the bag and compare its counts with what was published
   (the sim's ``FLIGHT_ENDED`` counts; for the autopilot's and this launcher's topics what this
   launcher's own subscriptions received or it sent): a missing message is an error (exit 3), and
   so is one more than was published (another flight's, ``EXTRA``).

Where it flies on the middleware (:mod:`lander_tools.fly.domain`): the user's ``ROS_DOMAIN_ID`` or
``--domain``, else a domain no other flight on this machine holds; discovery on this machine only
unless ``--network`` or the user's ``ROS_AUTOMATIC_DISCOVERY_RANGE``; a run file tells the verbs.
A second simulator or launcher in the domain refuses the flight before it starts (no bag) and is
one line when it appears mid-flight; the nodes refuse strangers' inputs (:mod:`lander_ros.strangers`).

Then :func:`~lander_tools.fly.summary.summary` is the summary it prints.

The modules, each one job, in the order they depend on each other:

==============  ===================================================================================
``plan``        what is flown and how it ended: FlightPlan, Action, FlightResult, the exit codes
``domain``      where it flies: the ROS domain and discovery range, the run file the verbs read
``checks``      the plan's names and ``--params`` file checked before anything starts
``processes``   the node processes: command lines, parameter files, output forwarding, the stop
``composed``    both nodes in one process (``--compose``)
``supervisor``  the launcher's own node: the watch, the pilot, the actions, the recorder, the counts
``timeline``    the timeline on the control grid: stops, ``pause_at``, actions put in force
``flight``      one flight being flown, and what it must meet (subscribers matched, the bag's counts)
``phases``      :func:`~lander_tools.fly.phases.fly` and its six phases
``summary``     the summary printed at the end
==============  ===================================================================================

ROS (rclpy, the message types) is imported where it is used, at the top of ``composed``,
``supervisor``, ``timeline``, ``flight`` and ``phases``; ``plan``, ``checks``, ``domain``,
``processes`` and ``summary`` are plain Python (scripted flights and sweeps build plans without ROS).

Exit status (:mod:`lander_tools.fly.plan`, documented in docs/flying.md):

====  ===========================================================
0     landed, or the time limit was reached while flying
1     crashed
2     error: a node failed to start or died, bad configuration,
      no state from the simulator
3     the flight ended as reported, but the bag misses messages that were published,
      or holds messages this flight did not publish (another flight's)
130   interrupted by Ctrl-C / SIGTERM (the bag is still closed validly)
====  ===========================================================
"""
