-- cps's scene script for CoppeliaSim 4.8+: executes a whole joint-target sequence inside
-- the simulator and records it, so that cps executes a trajectory in a handful of remote
-- calls instead of several per simulation step. The stand-in server (`cps-cli sim serve`)
-- has the same script built in; the protocol is documented in
-- crates/cps-coppelia/src/executor.rs.
--
-- Install: in the scene, add a simulation script (Add > Script > Simulation script,
-- Lua), paste this file, name the script object `cpsExecutor` and make it a child of the
-- robot (`/Panda/cpsExecutor`). The robot's joints must be `/<robot>_joint1..n` and its
-- tool point `/<robot>_tip`, as in the thesis's scene. For speed, turn real-time mode off
-- (or run CoppeliaSim headless, `coppeliaSim -h`): cps lets the simulation run freely
-- while the script works through the sequence.
--
-- Functions, called through the ZMQ remote API with
-- sim.callScriptFunction(name, scriptHandle, ...):
--   cpsLoad(targets)  targets: flat table of n * dof joint positions, one row per step.
--                     From the next step on, row k is commanded before step k and the
--                     joints, the tip's world pose and the clock are recorded after it;
--                     then the last row is held. Returns n.
--   cpsResult()       {done = k, total = n} while running; once k == n also
--                     time (n numbers), q (n * dof) and pose (n * 7: x y z qx qy qz qw).
--   cpsStop()         ends the sequence where it is (a stop asked of cps): no further row
--                     is commanded, the last one commanded is held; returns cpsResult()'s
--                     whole answer, with total = done.
-- Stopping the simulation forgets the sequence (simulation scripts start afresh).

sim = require 'sim'

local MAX_STEPS = 50000
local MAX_COORDINATE = 1e6

local joints, tip, dof
local targets, total, done
local recTime, recQ, recPose

local function reset()
    targets, total, done = nil, 0, 0
    recTime, recQ, recPose = {}, {}, {}
end

function sysCall_init()
    local me = sim.getObject('.')
    local robot = me
    if sim.getObjectAlias(me) == 'cpsExecutor' then
        -- A script object: the robot is its parent.
        robot = sim.getObjectParent(me)
    end
    local name = sim.getObjectAlias(robot)
    joints = {}
    while true do
        local h = sim.getObject('/' .. name .. '_joint' .. (#joints + 1), {noError = true})
        if h == -1 then
            break
        end
        joints[#joints + 1] = h
    end
    dof = #joints
    tip = sim.getObject('/' .. name .. '_tip')
    if dof == 0 then
        error('cpsExecutor: the robot /' .. name .. ' has no joints /' .. name .. '_joint1..n')
    end
    reset()
end

function cpsLoad(flat)
    if type(flat) ~= 'table' then
        error('cpsLoad(targets): argument 1 must be a table of joint positions')
    end
    local count = #flat
    if count == 0 or count % dof ~= 0 then
        error(string.format('cpsLoad(targets): %d numbers are not whole rows of %d joint positions', count, dof))
    end
    local n = count // dof
    if n > MAX_STEPS then
        error(string.format('cpsLoad(targets): %d steps, at most %d at once', n, MAX_STEPS))
    end
    for i = 1, count do
        local v = flat[i]
        if type(v) ~= 'number' or v ~= v or math.abs(v) > MAX_COORDINATE then
            error(string.format(
                'cpsLoad(targets): row %d, joint %d: %s is not a finite joint value of magnitude at most 1e6',
                (i - 1) // dof + 1, (i - 1) % dof + 1, tostring(v)))
        end
    end
    reset()
    targets, total = flat, n
    return n
end

function cpsResult()
    if not targets then
        error('cpsResult(): no sequence loaded (call cpsLoad first)')
    end
    local r = {done = done, total = total}
    if done == total then
        r.time, r.q, r.pose = recTime, recQ, recPose
    end
    return r
end

function cpsStop()
    if not targets then
        error('cpsStop(): no sequence loaded (call cpsLoad first)')
    end
    total = done
    return cpsResult()
end

function sysCall_actuation()
    if not targets or done >= total then
        return
    end
    local base = done * dof
    for j = 1, dof do
        local v = targets[base + j]
        if sim.isDynamicallyEnabled(joints[j]) then
            -- The physics engine moves this joint: command its motor.
            sim.setJointTargetPosition(joints[j], v)
        else
            sim.setJointPosition(joints[j], v)
        end
    end
end

function sysCall_sensing()
    if not targets or done >= total then
        return
    end
    done = done + 1
    recTime[done] = sim.getSimulationTime()
    local base = (done - 1) * dof
    for j = 1, dof do
        recQ[base + j] = sim.getJointPosition(joints[j])
    end
    local pose = sim.getObjectPose(tip, sim.handle_world)
    base = (done - 1) * 7
    for m = 1, 7 do
        recPose[base + m] = pose[m]
    end
end

function sysCall_cleanup()
    reset()
end
