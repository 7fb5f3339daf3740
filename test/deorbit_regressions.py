"""Hard flights of the de-orbit sweeps kept as named regressions: each is named by what makes it
hard and spelled out by its physical conditions (the dispersions it flies: wind, gusts, thrust,
mass, density and cant errors, where on the orbit it starts), not by its number in a sweep, so a
change to a sweep's dispersions or seed leaves the flight the tests guard as it is.

:func:`flown` flies one as the sweep's loop does (:func:`lander_tools.sweep.flight.fly_case`: the
same scene, demand schedule, control instants and requests), a control period at a time.
"""
from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

from lander_autopilot.controllers import Demand, make_controller
from lander_autopilot.controllers.base import REQUEST_DEPLOY_PARACHUTE
from lander_sim.physics.state import StateView
from lander_sim.simulation import Simulation
from lander_tools.sweep.case_scene import flown_scene, nominal_scene
from lander_tools.sweep.dispersion import FlightCase
from lander_tools.sweep.flight import control_period, demand_schedule
from lander_tools.sweep.spec import load_spec

SWEEPS = Path(__file__).resolve().parents[1] / "sweeps"
SPEC = SWEEPS / "deorbit-200km.yaml"  # from a 200 km circular orbit
SPEC_0 = SWEEPS / "deorbit.yaml"  # scenario 0's orbit


class Regression(NamedTuple):
    """A dispersed flight kept as a regression: what makes it hard, the sweep whose scene, controllers
    and demand it flies, the seed of its gusts' random stream, and its dispersions (the
    :class:`~lander_tools.sweep.dispersion.FlightCase` fields that are not zero)."""

    what: str
    spec: Path
    gusts: tuple[int, int]
    case: dict[str, Any]

    def flight_case(self) -> FlightCase:
        seed, stream = self.gusts
        return FlightCase(index=stream, seed=seed, **self.case)

    @property
    def wind(self) -> float:
        """The mean wind's speed [m/s]."""
        return math.hypot(*self.case["wind_mean_W"])


def flown(r: Regression, controller_index: int, **params: object) -> Iterator[tuple[StateView, Any, Simulation]]:
    """The regression's flight with its sweep's controller ``controller_index`` (0 scheduled, 1 MPC;
    ``params`` over the sweep's), a control period at a time: yields the state the law was given,
    the law after its update, and the simulation after the period; the spec's duration at most,
    or until the lander is down (the sweep's loop). A chute request deploys the chute."""
    spec = load_spec(r.spec)
    case = r.flight_case()
    scene0 = nominal_scene(spec)
    choice = spec.controllers[controller_index]
    ctrl = make_controller(choice.name, scene0.vehicle, **{**dict(choice.params), **params})
    sim = Simulation(flown_scene(spec, case))
    n_sub, period = control_period(spec, sim.dt)
    h_before, h_after, t_change = demand_schedule(spec, scene0, case)
    before, after = Demand(altitude=h_before), Demand(altitude=h_after)
    for k in range(int(math.floor(spec.end.duration / period + 1e-9))):
        t = k * period
        s = sim.state()
        out = ctrl.update(t, s, after if t >= t_change else before)
        if any(req.kind == REQUEST_DEPLOY_PARACHUTE for req in out.requests):
            sim.deploy_parachute()
        sim.set_throttles(out.throttles)
        sim.step(n_sub)
        assert sim.phase.name == "FLYING", sim.phase
        yield s, ctrl, sim


STRONG_WIND = Regression(
    "5.6 m/s of wind under the canopy", SPEC, gusts=(20250115, 88),
    case=dict(
        wind_mean_W=(-5.218135192210597, 1.170203896965558, -1.571868808517611),
        wind_gust=0.7380138751724534,
        mass_error=-0.01336959137005481,
        thrust_error=(-0.021588631116198832, -0.013638635416915575, 0.009080990243499787, -0.011925509935469623),
        orbit_altitude=6800.982329173239,
        orbit_phase=3.4511429326555194,
        density_error=-0.02652713563607234,
        thruster_cant=(0.0008273790227294437, 0.0031630583611001943, 0.0021636977359341504, 0.003799487189121014),
        thruster_cant_azimuth=(0.6502704636461901, 2.7167622627421557, 2.696218777735985, 5.030802261497907),
    ))
STEADY_WIND = Regression(
    "4.4 m/s of steady wind, small gusts", SPEC, gusts=(20250115, 55),
    case=dict(
        wind_mean_W=(-0.5755654770804046, -2.9894845434748603, -3.176405599560825),
        wind_gust=0.09757966568913679,
        mass_error=0.015375697588962452,
        thrust_error=(-0.0150504796628168, -0.015812689450820924, 0.021937980520224297, -0.028448692562617197),
        orbit_altitude=8470.006127573855,
        orbit_phase=6.05079115141546,
        density_error=-0.02491088328285218,
        thruster_cant=(0.007869184010155583, 0.0008566147670736921, 0.001522582559960753, 0.008096173808548908),
        thruster_cant_azimuth=(0.3709332736424177, 2.769957815404004, 0.4533705011499791, 3.1391431511653356),
    ))
WINDY_DOWNDRAFT = Regression(
    "5.4 m/s of wind, 3.9 m/s of it downdraft: a thruster pinned at full braking", SPEC, gusts=(20250115, 196),
    case=dict(
        wind_mean_W=(-4.14947324201892, 2.110205264020782, 2.721781765774971),
        wind_gust=0.5526987243079902,
        mass_error=0.01619480365114005,
        thrust_error=(-0.009494891955686285, -0.00986018236558921, -0.007386595414524404, -0.021394919517443767),
        orbit_altitude=-4295.941999984112,
        orbit_phase=4.516109921365507,
        density_error=0.2835122465542737,
        thruster_cant=(0.005629243858144319, 0.007306727211408085, 0.007918130057229994, 0.006035255065118723),
        thruster_cant_azimuth=(4.760928272809099, 2.947981805976462, 2.4973038981993265, 1.069615153519514),
    ))
WEAK_THRUSTER_DRIFT = Regression(
    "5.6 m/s of drift under the canopy and a thruster 3 % weak", SPEC, gusts=(20250115, 261),
    case=dict(
        wind_mean_W=(1.953372053199563, -1.3636795551987377, 5.162069995402893),
        wind_gust=0.17955587074088508,
        mass_error=0.015019020495345817,
        thrust_error=(-0.0071041446278624285, 0.025967117583591312, -0.01903133027382014, 0.02987081746925603),
        orbit_altitude=-5510.648586994069,
        orbit_phase=3.79867749163142,
        density_error=0.05018626600001064,
        thruster_cant=(0.004849909817703026, 0.0032151513499500115, 0.003296669960131294, 0.006234361023175294),
        thruster_cant_azimuth=(0.6965252401331808, 2.0708297350695863, 3.2598062808382733, 1.5686382272345403),
    ))
DRIFT = Regression(
    "2.5 m/s of drift under the canopy, 2.9 m/s of horizontal wind", SPEC, gusts=(20250115, 38),
    case=dict(
        wind_mean_W=(2.9124641431559, 1.2770542755293912, 2.3025336122369864),
        wind_gust=0.9504627953265804,
        mass_error=0.0032401423142512133,
        thrust_error=(-0.00030336970179233383, -0.02808343611744774, -0.003964302812197961, 0.026805070947402948),
        orbit_altitude=-926.0839823655606,
        orbit_phase=3.697078343319145,
        density_error=0.250946350958511,
        thruster_cant=(0.0016143444640201088, 0.006540738669998454, 0.002259282369110563, 0.0008428836411242856),
        thruster_cant_azimuth=(6.051462233431345, 2.934339372015827, 3.87958760037417, 2.0290690403076748),
    ))
THIN_AIR_DOWNDRAFT = Regression(
    "density -12.9 %, 1.1 m/s of downdraft", SPEC, gusts=(20250115, 188),
    case=dict(
        wind_mean_W=(-2.4166850943165956, 2.8943611354111725, 1.273464031761749),
        wind_gust=0.7014254004585656,
        mass_error=0.011394819651613635,
        thrust_error=(-0.01644680261002359, -0.024514857793350872, 0.015696015762918784, 0.00342441224130189),
        orbit_altitude=5389.193658802809,
        orbit_phase=6.155087232899373,
        density_error=-0.1293042768899733,
        thruster_cant=(0.0008109833348176621, 0.0056647228045603, 0.0066569245714909984, 0.001304108126124851),
        thruster_cant_azimuth=(2.859401871088259, 2.653545805350993, 5.785595765728621, 3.697994869419484),
    ))
NORTH_WIND = Regression(
    "6.2 m/s of wind from the north: the braking rides the mixer's ceiling", SPEC, gusts=(20250115, 140),
    case=dict(
        wind_mean_W=(-0.4456166734804853, 1.897518806865264, -6.227501142104376),
        wind_gust=0.7790245607414296,
        mass_error=-0.013288058453904062,
        thrust_error=(0.02526313913840761, 0.026363477188769406, 0.014201435826266769, -0.028468042292245047),
        orbit_altitude=8729.48717612019,
        orbit_phase=5.275787841908022,
        density_error=0.09427246170885506,
        thruster_cant=(0.0008581328486331101, 0.006956852553395985, 0.005210327188863022, 0.003985948986784385),
        thruster_cant_azimuth=(3.4228218356581377, 6.0565548141969785, 3.5866532988439674, 4.5515932548801645),
    ))
EAST_NORTH_WIND = Regression(
    "5.2 m/s east and 3.3 m/s north of wind", SPEC, gusts=(20250115, 164),
    case=dict(
        wind_mean_W=(-0.8822408781054132, -5.280238977820791, 3.289466199063499),
        wind_gust=0.28073369654483393,
        mass_error=0.011400245186074288,
        thrust_error=(0.0048878054550075545, -0.019561871899800954, -0.0142826789988794, 0.010776413939216543),
        orbit_altitude=725.0024906206872,
        orbit_phase=1.0973159256720066,
        density_error=0.21938382707430565,
        thruster_cant=(0.0019628787496330322, 0.0004759340293324594, 0.007857032196646543, 0.0009493355411151492),
        thruster_cant_azimuth=(2.376355144601369, 6.0737994260938075, 5.408559550712922, 2.781402795865575),
    ))
DENSE_GUSTY = Regression(
    "4.7 m/s of wind, 1.3 x the model's drag", SPEC, gusts=(20250115, 24),
    case=dict(
        wind_mean_W=(2.342043247553941, -3.0139214303243036, -2.704212374680379),
        wind_gust=0.8081471671360269,
        mass_error=0.00828307964004733,
        thrust_error=(-0.01124622330778429, -0.0007944266050371879, 0.02895094550561713, 0.029095404006229036),
        orbit_altitude=-5693.416033249768,
        orbit_phase=0.37657535649252916,
        density_error=0.2902499295489959,
        thruster_cant=(0.0018539256610366304, 0.005278835325713017, 0.0017821348101452726, 0.006547413228849333),
        thruster_cant_azimuth=(6.243690356523027, 3.265795164013011, 5.455269690975924, 2.556913199537581),
    ))
HELD_OUT_WIND = Regression(
    "3.2 m/s of wind, density -13 %, a thruster 2.7 % weak", SPEC, gusts=(20250115, 233),
    case=dict(
        wind_mean_W=(0.1762598344974861, 0.6991983675825977, 3.1205097455937616),
        wind_gust=0.7574294212192333,
        mass_error=0.012802223239791289,
        thrust_error=(-0.02708599695228308, 0.020395029622799744, -0.003477281138001529, 0.009548667644996602),
        orbit_altitude=4908.563605829555,
        orbit_phase=4.932030082002902,
        density_error=-0.12991265596061952,
        thruster_cant=(0.006095970540540659, 0.0005793916142021343, 0.0034496165847472866, 0.006391910077855034),
        thruster_cant_azimuth=(0.9006218432465702, 0.7181971905816947, 1.607535650349309, 1.577861682830667),
    ))
SHORT_STEPS = Regression(
    "scenario 0's orbit: the programme's last steps 15 ms", SPEC_0, gusts=(20250114, 96),
    case=dict(
        wind_mean_W=(1.4999064570099674, 1.2651800129468045, -1.2345000892294151),
        wind_gust=0.9004855400778307,
        mass_error=0.004152532505134095,
        thrust_error=(0.02967203254950728, -0.0159094223263553, -0.0030572468389163422, -0.028492536134438962),
        orbit_altitude=-8447.506858423845,
        orbit_phase=3.8949215205789542,
        density_error=0.08221952159815182,
        thruster_cant=(0.006674746063555912, 0.007968311352442779, 0.0030315280985113765, 0.00035491148920407305),
        thruster_cant_azimuth=(0.5198472899559343, 0.7366906263282075, 5.485151996693812, 2.5260257779543096),
    ))
OWN_TORQUE = Regression(
    "scenario 0's orbit: the thrusters' own torque takes ~5 % of the collective", SPEC_0, gusts=(20250114, 78),
    case=dict(
        wind_mean_W=(-0.5491431152147316, 2.0091561506625357, 0.3242903433497904),
        wind_gust=0.7913773946994663,
        mass_error=0.014329296374201505,
        thrust_error=(0.01829009525453456, 0.028150948830834854, -0.022560519501757064, 0.02829361418157641),
        orbit_altitude=-1570.1532115541831,
        orbit_phase=5.4161532419894405,
        density_error=-0.15005800167753322,
        thruster_cant=(0.0018665054846457084, 0.004588668261112616, 0.008345231412501894, 0.003815227061974433),
        thruster_cant_azimuth=(0.1820318314238928, 5.031566561263301, 2.7104961863685944, 0.25333756007012137),
    ))
LATE_END = Regression(
    "scenario 0's orbit: the plan's end recedes in its last second", SPEC_0, gusts=(20250114, 203),
    case=dict(
        wind_mean_W=(1.675997995405098, 1.8573061390431025, 0.10905338834869018),
        wind_gust=0.7496876277496934,
        mass_error=0.013398886698516643,
        thrust_error=(0.005600931971232792, -0.005348981218897736, -0.01501537347048628, 0.006385171330218348),
        orbit_altitude=7510.126332241296,
        orbit_phase=5.139039985262867,
        density_error=0.12273414996477516,
        thruster_cant=(0.001941689714628037, 0.0033156662010410468, 0.003542982193654315, 0.0055156068122309936),
        thruster_cant_azimuth=(2.712091734706056, 4.886932042865973, 5.820877338151934, 0.7670252985936018),
    ))
