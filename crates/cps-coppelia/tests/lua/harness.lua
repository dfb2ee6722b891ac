-- Runs configs/coppeliasim/cpsExecutor.lua (path in arg[1]) against a mock `sim` module
-- standing in for CoppeliaSim 4.8: a three-joint robot /Arm whose joint 3 is dynamically
-- enabled, a tip whose pose is a known function of the joints, and a clock. Checks the
-- protocol of crates/cps-coppelia/src/executor.rs: the sentences of cpsLoad's refusals,
-- row k commanded before step k and recorded after it, the recording's shape, the last
-- row held, cpsResult before and after. Exits non-zero on the first failure.

local joints = {[11] = 0.0, [12] = 0.0, [13] = 0.0}
local motorTarget = {}
local time = 0.0
local objects = {['/Arm_joint1'] = 11, ['/Arm_joint2'] = 12, ['/Arm_joint3'] = 13, ['/Arm_tip'] = 20}
local mock = {
    handle_world = -1,
    getObject = function(path, options)
        if path == '.' then return 30 end
        local h = objects[path]
        if h then return h end
        if options and options.noError then return -1 end
        error('object does not exist: ' .. path)
    end,
    getObjectAlias = function(h)
        if h == 30 then return 'cpsExecutor' end
        if h == 10 then return 'Arm' end
        error('alias of ' .. h)
    end,
    getObjectParent = function(h)
        assert(h == 30)
        return 10
    end,
    isDynamicallyEnabled = function(h) return h == 13 end,
    setJointPosition = function(h, v)
        assert(h ~= 13, 'a dynamic joint is commanded through its motor')
        joints[h] = v
    end,
    setJointTargetPosition = function(h, v)
        assert(h == 13, 'a kinematic joint is set directly')
        motorTarget[h] = v
    end,
    getJointPosition = function(h) return joints[h] end,
    getSimulationTime = function() return time end,
    getObjectPose = function(h, rel)
        assert(h == 20 and rel == -1)
        return {joints[11], joints[12], joints[13], 0.0, 0.0, 0.0, 1.0}
    end,
}
package.preload['sim'] = function() return mock end
dofile(arg[1])

-- One simulation step as CoppeliaSim runs it: actuation, physics (the motor reaches half
-- of its target), sensing.
local function step()
    sysCall_actuation()
    time = time + 0.01
    if motorTarget[13] then
        joints[13] = joints[13] + 0.5 * (motorTarget[13] - joints[13])
    end
    sysCall_sensing()
end

local function refuses(expected, ...)
    local ok, message = pcall(...)
    assert(not ok, 'expected a refusal: ' .. expected)
    assert(string.find(tostring(message), expected, 1, true),
        'expected "' .. expected .. '" in: ' .. tostring(message))
end

sysCall_init()
refuses('no sequence loaded', cpsResult)
refuses('no sequence loaded', cpsStop)
refuses('argument 1 must be a table', cpsLoad, 'q')
refuses('are not whole rows of 3', cpsLoad, {1, 2, 3, 4})
refuses('row 2, joint 1: ', cpsLoad, {0, 0, 0, 0 / 0, 0, 0})
refuses('nan is not a finite joint value', cpsLoad, {0, 0, 0, 0 / 0, 0, 0})
refuses('row 1, joint 3: 10000000.0 is not', cpsLoad, {0, 0, 1e7})
local big = {}
for i = 1, 3 * 50001 do big[i] = 0 end
refuses('50001 steps, at most 50000', cpsLoad, big)

-- Steps before a load change nothing and record nothing.
step()
assert(cpsLoad({0.1, 0.2, 0.4, 0.3, 0.4, 0.8}) == 2)
local r = cpsResult()
assert(r.done == 0 and r.total == 2 and r.time == nil)
step()
r = cpsResult()
assert(r.done == 1 and r.total == 2 and r.q == nil)
step()
step()  -- past the end: the last row is held, nothing more is recorded
r = cpsResult()
assert(r.done == 2 and r.total == 2)
assert(#r.time == 2 and #r.q == 6 and #r.pose == 14)
assert(math.abs(r.time[1] - 0.02) < 1e-12 and math.abs(r.time[2] - 0.03) < 1e-12)
-- Kinematic joints are where they were commanded; the dynamic one lags its motor.
assert(r.q[1] == 0.1 and r.q[2] == 0.2 and math.abs(r.q[3] - 0.2) < 1e-12)
assert(r.q[4] == 0.3 and r.q[5] == 0.4 and math.abs(r.q[6] - 0.5) < 1e-12)
-- The pose row k is the tip after step k: x y z qx qy qz qw.
assert(r.pose[8] == 0.3 and r.pose[9] == 0.4 and r.pose[14] == 1.0)
assert(joints[11] == 0.3 and motorTarget[13] == 0.8)
-- A stop ends a sequence where it is: what was done is the whole answer, the last row
-- commanded is held and no further row is.
assert(cpsLoad({0.5, 0.5, 0.5, 0.6, 0.6, 0.6, 0.7, 0.7, 0.7}) == 3)
step()
r = cpsStop()
assert(r.done == 1 and r.total == 1 and #r.time == 1 and #r.q == 3)
step()
assert(cpsResult().done == 1 and joints[11] == 0.5)
-- A new load starts afresh; cleanup forgets it.
assert(cpsLoad({1, 1, 1}) == 1)
assert(cpsResult().done == 0)
sysCall_cleanup()
refuses('no sequence loaded', cpsResult)
print('cpsExecutor.lua keeps the protocol')
