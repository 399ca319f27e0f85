import libsumo, sys
libsumo.start(["sumo","-n","/work/main/networks/straight/straight.net.xml","--step-length","0.1","--lateral-resolution","0.4","--no-step-log"])
libsumo.route.add("r",["WE"])
libsumo.vehicletype.copy("DEFAULT_VEHTYPE","t")
libsumo.vehicletype.setParameter("t","laneChangeModel.lcAccelLat","3.0")
libsumo.vehicle.add("v","r",typeID="t",departSpeed="10")
libsumo.vehicle.setLaneChangeMode("v", 512)
libsumo.simulationStep()
v = float(sys.argv[1])
for k in range(40):
    libsumo.vehicle.setMaxSpeedLat("v", abs(v))
    libsumo.vehicle.changeSublane("v", 1.0 if v > 0 else -1.0)
    libsumo.simulationStep()
    if k % 4 == 0: print(k, round(libsumo.vehicle.getLateralLanePosition("v"),3), libsumo.vehicle.getLaneID("v"), round(libsumo.vehicle.getLateralSpeed("v"),3))
