"""Watch and steer a running flight live (docs/live.md): Foxglove bridge, student page, CLI verbs.

* :mod:`.views`   what the channels show, from a state (plain numpy: frames, trail, plumes)
* :mod:`.link`    a ROS client of the flight (services, parameters, topics): the verbs and the bridge
* :mod:`.bridge`  the ``lander live`` process: rclpy node + foxglove WebSocket server
* :mod:`.clientinput`  what clients may send the bridge, checked for shape before forwarding
* :mod:`.page`    the student page's HTTP server; ``web/`` its static files (3-D view: three.js)
* :mod:`.replay`  a recorded flight (bag) as the page's state records (``lander view BAG``)
* :mod:`.verbs`   the CLI verbs' shared plumbing (``lander demand``, ``wind``, ``pause``, ...)

See docs/live.md.
"""
