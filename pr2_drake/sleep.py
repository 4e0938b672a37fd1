"""Object sleeping: free objects that rest with nothing near skip the contact computation.

Every 1 ms physics step computes the contacts of every free object (task 6: nine objects, 44
collision shapes resting on tables), although most of them stand still for the whole episode.
An :class:`ObjectSleeper` puts such objects to sleep and wakes them before anything can touch
them:

- **Asleep**: the object's proximity geometries are filtered out against every geometry (a
  transient declaration of the SceneGraph context's collision filter manager: no contact is
  computed), its velocity is set to exactly zero when it falls asleep, and the grasp system
  applies a force of exactly -m g at its centre of mass (:class:`pr2_drake.grasp.GraspSystem`),
  which cancels its weight bit for bit: it stays exactly where it rested.
- **Falls asleep** when it has been at rest (speed below ``rest_speed``) for ``rest_time``,
  nothing that moves is within ``sleep_distance`` of it (robot bodies, other moving bodies,
  moving objects), it is not held, and every awake object near it (within
  ``sleep_distance``) falls asleep with it (an object never rests on a sleeping one).
- **Wakes** when a robot body (or any other body that is not welded to the world), or an
  awake object that moves, comes within ``wake_distance`` of it, or when it is held. It
  wakes at rest, where it slept, with its contacts back: no jump.

Distances are gaps between bounding spheres: each body's sphere is centred on its origin and
encloses its collision shapes, so ``gap = |p_WBo - p_WOo| - r_B - r_O`` [m] is a lower bound
of the distance between their surfaces. A body moving at speed v crosses at most
``v * check_period`` between two checks, so with the defaults (20 ms, 0.15 m) anything slower
than 7.5 m/s finds the object awake before it touches it.

Checks run at the simulated times k * ``check_period`` (see
:meth:`pr2_drake.episode.Episode.advance_to`), whatever chunks a driver advances in, so the
same episode gives the same trajectory bit for bit under every driver.
"""

import math
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import (
    Box,
    Capsule,
    CollisionFilterDeclaration,
    Convex,
    Cylinder,
    Ellipsoid,
    GeometrySet,
    Mesh,
    Role,
    Sphere,
)
from pydrake.multibody.math import SpatialVelocity


@dataclass
class SleepSettings:
    """When free objects sleep (see :mod:`pr2_drake.sleep`).

    Attributes:
        enabled: False = no object ever sleeps (the physics of every step as without it).
        check_period: simulated time between two checks [s].
        rest_speed: an object is at rest when its speed [m/s] and angular speed [rad/s] are
            both below this.
        rest_time: at rest this long [s] (at every check) before it may sleep.
        wake_distance: a moving body whose bounding sphere comes within this gap [m] of a
            sleeping object's wakes it.
        sleep_distance: an object sleeps only with no moving body within this gap [m]
            (> wake_distance: hysteresis).
    """

    enabled: bool = True
    check_period: float = 0.02
    rest_speed: float = 0.01
    rest_time: float = 0.5
    wake_distance: float = 0.15
    sleep_distance: float = 0.3

    def validate(self) -> None:
        """Raise ValueError naming the first bad field."""
        if not isinstance(self.enabled, bool):
            raise ValueError(f"sleep.enabled must be true or false, got {self.enabled!r}")
        for name, upper in (("check_period", 1.0), ("rest_speed", math.inf),
                            ("rest_time", math.inf), ("wake_distance", math.inf),
                            ("sleep_distance", math.inf)):
            v = getattr(self, name)
            if (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                    or not 0 < v <= upper):
                bound = "" if math.isinf(upper) else f" and at most {upper:g}"
                raise ValueError(f"sleep.{name} must be a positive finite number{bound}, "
                                 f"got {v!r}")
        if self.sleep_distance <= self.wake_distance:
            raise ValueError(f"sleep.sleep_distance ({self.sleep_distance}) must be greater "
                             f"than sleep.wake_distance ({self.wake_distance})")


def shape_radius(shape) -> float:
    """Radius [m] of a sphere about the shape's frame origin that encloses the shape."""
    if isinstance(shape, Sphere):
        return shape.radius()
    if isinstance(shape, Box):
        return 0.5 * float(np.linalg.norm(shape.size()))
    if isinstance(shape, Cylinder):
        return math.hypot(shape.radius(), 0.5 * shape.length())
    if isinstance(shape, Capsule):
        return shape.radius() + 0.5 * shape.length()
    if isinstance(shape, Ellipsoid):
        return max(shape.a(), shape.b(), shape.c())
    if isinstance(shape, (Mesh, Convex)):
        hull = shape.GetConvexHull()
        return max(float(np.linalg.norm(hull.vertex(i))) for i in range(hull.num_vertices()))
    raise ValueError(f"object sleeping: no bounding radius for a {type(shape).__name__}")


def body_radius(plant, inspector, body) -> float:
    """Radius [m] of a sphere centred on the body's origin enclosing its collision shapes."""
    r = 0.0
    for g in plant.GetCollisionGeometriesForBody(body):
        p = np.linalg.norm(inspector.GetPoseInFrame(g).translation())
        r = max(r, float(p) + shape_radius(inspector.GetShape(g)))
    return r


class ObjectSleeper:
    """Decides, at each check, which free graspable objects of a testbed sleep, and applies it.

    Args:
        testbed: the :class:`pr2_drake.testbed.Testbed`.
        settings: the thresholds.

    Only graspables that are free bodies (a floating base) are managed; :attr:`active` is
    False when there is none (nothing to do). State lives in the diagram's context (the
    filter declarations, the grasp system's set of sleepers, the plant state) except the
    bookkeeping here (the transient filter ids and rest clocks), which :meth:`reset` clears.
    """

    def __init__(self, testbed, settings: SleepSettings):
        settings.validate()
        self.settings = settings
        self.testbed = testbed
        self._filter_ids: dict[int, object] = {}  # slot -> transient filter id
        self._rest_since: list[float | None] = []
        plant, sg = testbed.plant, testbed.scene_graph
        inspector = sg.model_inspector()
        self._managed: list[int] = []  # graspable indices
        self._bodies = []  # their body indices
        for i, g in enumerate(testbed.scene.graspables):
            body = plant.get_body(g.body)
            if body.is_floating_base_body() and plant.GetCollisionGeometriesForBody(body):
                self._managed.append(i)
                self._bodies.append(g.body)
        self.active = bool(settings.enabled and self._managed)
        if not self.active:
            return
        managed = set(self._bodies)
        anchored = {b.index() for b in plant.GetBodiesWeldedTo(plant.world_body())}
        self._movers = []  # bodies that move and can touch: the robot, any other free body
        for k in range(plant.num_bodies()):
            body = plant.get_body(_body_index(k))
            if (body.index() in managed or body.index() in anchored
                    or not plant.GetCollisionGeometriesForBody(body)):
                continue
            self._movers.append(body.index())
        self._r_obj = np.array([body_radius(plant, inspector, plant.get_body(b))
                                for b in self._bodies])
        self._r_mov = np.array([body_radius(plant, inspector, plant.get_body(b))
                                for b in self._movers])
        self._geoms = [list(plant.GetCollisionGeometriesForBody(plant.get_body(b)))
                       for b in self._bodies]
        self._all = GeometrySet(list(inspector.GetAllGeometryIds(Role.kProximity)))
        self.reset()

    # -- bookkeeping --------------------------------------------------------------------------
    def reset(self, context=None) -> None:
        """Forget every sleeper (call when the episode restarts). With ``context``: also
        remove the filter declarations still active there and clear the grasp system's set."""
        if not self.active:
            return
        if context is not None:
            mgr = self._filters(context)
            for fid in self._filter_ids.values():
                if mgr.IsActive(fid):
                    mgr.RemoveDeclaration(fid)
            self._grasp().set_sleeping(self._grasp_context(context), ())
        self._filter_ids = {}
        self._rest_since = [None] * len(self._bodies)

    @property
    def sleeping(self) -> list[str]:
        """Names of the sleeping objects."""
        names = [g.name for g in self.testbed.scene.graspables]
        return sorted(names[self._managed[s]] for s in self._filter_ids)

    @property
    def tolerance(self) -> float:
        """Times this close [s] to a check time count as that check time."""
        return 1e-9 * self.settings.check_period

    def next_check(self, t: float) -> float:
        """The first check time after ``t`` [s] (on the grid k * check_period), the one at
        ``t`` excluded (within :attr:`tolerance`)."""
        p = self.settings.check_period
        return (math.floor(t / p + 1e-9) + 1) * p

    # -- the check ----------------------------------------------------------------------------
    def check(self, context) -> None:
        """Update who sleeps from the state in the root ``context`` (between AdvanceTo
        calls, at a check time)."""
        if not self.active:
            return
        s = self.settings
        plant = self.testbed.plant
        pc = plant.GetMyMutableContextFromRoot(context)
        t = context.get_time()
        n = len(self._bodies)
        p_obj = np.empty((n, 3))
        moving = np.zeros(n, bool)
        for i, b in enumerate(self._bodies):
            body = plant.get_body(b)
            p_obj[i] = plant.EvalBodyPoseInWorld(pc, body).translation()
            V = plant.EvalBodySpatialVelocityInWorld(pc, body)
            at_rest = (np.linalg.norm(V.translational()) < s.rest_speed
                       and np.linalg.norm(V.rotational()) < s.rest_speed)
            asleep = i in self._filter_ids
            moving[i] = not asleep and not at_rest
            if asleep or not at_rest:
                self._rest_since[i] = None
            elif self._rest_since[i] is None:
                self._rest_since[i] = t
        p_mov = np.array([plant.EvalBodyPoseInWorld(pc, plant.get_body(b)).translation()
                          for b in self._movers]).reshape(-1, 3)
        gap_mov = (np.linalg.norm(p_obj[:, None] - p_mov[None], axis=2) - self._r_obj[:, None]
                   - self._r_mov[None])
        gap_obj = (np.linalg.norm(p_obj[:, None] - p_obj[None], axis=2) - self._r_obj[:, None]
                   - self._r_obj[None])
        np.fill_diagonal(gap_obj, np.inf)
        # The nearest gap to anything that moves: robot and free bodies, moving objects.
        near = np.min(gap_mov, axis=1, initial=np.inf)
        near = np.minimum(near, np.min(np.where(moving[None], gap_obj, np.inf), axis=1))
        held = self._held(context)
        changed = False
        for i in list(self._filter_ids):
            if near[i] < s.wake_distance or i in held:
                self._wake(context, i)
                self._rest_since[i] = t
                changed = True
        awake = [i for i in range(n) if i not in self._filter_ids]
        ready = {i for i in awake
                 if self._rest_since[i] is not None and t - self._rest_since[i]
                 >= s.rest_time - 1e-9 and near[i] > s.sleep_distance and i not in held}
        # Awake objects near each other sleep together or not at all (one may rest on another).
        for group in _groups(awake, gap_obj, s.sleep_distance):
            if all(i in ready for i in group):
                for i in group:
                    self._sleep(context, pc, i)
                changed = True
        if changed:
            self._grasp().set_sleeping(self._grasp_context(context),
                                       tuple(sorted(self._managed[i] for i in self._filter_ids)))

    # -- helpers ------------------------------------------------------------------------------
    def _sleep(self, context, pc, i: int) -> None:
        plant = self.testbed.plant
        plant.SetFreeBodySpatialVelocity(pc, plant.get_body(self._bodies[i]),
                                         SpatialVelocity(np.zeros(3), np.zeros(3)))
        decl = CollisionFilterDeclaration().ExcludeBetween(GeometrySet(self._geoms[i]),
                                                           self._all)
        self._filter_ids[i] = self._filters(context).ApplyTransient(decl)
        self._rest_since[i] = None

    def _wake(self, context, i: int) -> None:
        fid = self._filter_ids.pop(i)
        mgr = self._filters(context)
        if mgr.IsActive(fid):
            mgr.RemoveDeclaration(fid)

    def _filters(self, context):
        sg = self.testbed.scene_graph
        return sg.collision_filter_manager(sg.GetMyMutableContextFromRoot(context))

    def _grasp(self):
        return self.testbed.grasp

    def _grasp_context(self, context):
        return self.testbed.grasp.GetMyMutableContextFromRoot(context)

    def _held(self, context) -> set[int]:
        """Slots of the managed objects a hand holds."""
        grasp = self.testbed.grasp
        g = grasp.held_graspable(grasp.GetMyContextFromRoot(context))
        return {self._managed.index(g)} if g is not None and g in self._managed else set()


def _groups(members: list[int], gap: np.ndarray, distance: float) -> list[list[int]]:
    """Connected components of ``members`` under 'gap < distance'."""
    left, groups = set(members), []
    while left:
        stack = [min(left)]
        left.discard(stack[0])
        group = []
        while stack:
            i = stack.pop()
            group.append(i)
            for j in [j for j in left if gap[i, j] < distance]:
                left.discard(j)
                stack.append(j)
        groups.append(sorted(group))
    return groups


def _body_index(k: int):
    from pydrake.multibody.tree import BodyIndex

    return BodyIndex(k)
