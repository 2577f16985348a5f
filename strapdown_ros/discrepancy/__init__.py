"""The discrepancy workflow: where a recording and its model disagree and which effect is missing."""
