"""Tool frames (TCP) calibrated from flange poses, Xiong et al. 2012."""
