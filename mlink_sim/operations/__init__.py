"""The operations on a running network, a standalone slave or the impairing proxy: declared once
(:data:`OPERATIONS`), with the kinds of their arguments and the rules for their values (:mod:`.args`), the
impairments and faults they name (:mod:`.specs`) and the text a user reads (:mod:`.render`). Every surface —
the control endpoints, the command line, the HTTP API, the Python API, the pytest plugin, the timeline — is built
from this table (docs/control.md, docs/architecture.md "One definition, many surfaces").

Sans-I/O: no clock, no socket; values in, values or :class:`OpError` out.
"""

from .args import ERROR_KINDS, Arg, Kind, OpError, check_speed, station_name
from .render import alarm_text, card_text, event_text, leds_text, station_text
from .specs import fault_of, impairment_of, parse_fault_text
from .methods import NetworkOperations, param_value
from .table import ENDPOINTS, OPERATIONS, Operation, operation, parse_request, request_of, served_by

__all__ = ["ERROR_KINDS", "ENDPOINTS", "OPERATIONS", "Arg", "Kind", "NetworkOperations", "OpError", "Operation",
           "alarm_text", "card_text", "param_value",
           "check_speed", "event_text", "fault_of", "impairment_of", "leds_text", "operation", "parse_fault_text",
           "parse_request", "request_of", "served_by", "station_name", "station_text"]
