"""Strapdown INS in WGS-84 and its error-state EKF (navigator `ins_ekf`)."""

from testbench.navigation.ins.ekf import ErrorStateEKF
from testbench.navigation.ins.mechanization import StrapdownINS, strapdown_step
from testbench.navigation.ins.navigator import InsEkfNavigator

__all__ = ["ErrorStateEKF", "InsEkfNavigator", "StrapdownINS", "strapdown_step"]
