"""All CLI sub-commands, one module each; add new ones to COMMANDS."""

from guardid.commands.capture import capture
from guardid.commands.excite import excite
from guardid.commands.export import export
from guardid.commands.fake_port import fake_port
from guardid.commands.identify import identify, validate
from guardid.commands.ports import ports
from guardid.commands.reproduce import reproduce
from guardid.commands.simulate import simulate

COMMANDS = [simulate, excite, capture, identify, validate, fake_port, ports, reproduce, export]
