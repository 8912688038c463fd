"""Declared parameters for the Python plugins (recognizers, compensators): each class
declares PARAMETERS = {name: (type, default, check)} once; configure() takes the text values
the C++ side passes (`--recognizer-param name=value`, a nodelet's `~recognizer_params` or
`~compensator_params`) and raises ValueError whose message starts with the bad or unknown
name, never keeping a partial setting."""


class Configurable:
    """Base of the Python plugins: PARAMETERS = {name: (type, default, check)}, check(value) ->
    bool. After configure() has set them, `configured()` is called (a recognizer resets)."""

    PARAMETERS = {}

    def __init__(self):
        self.params = {name: default for name, (_, default, _) in self.PARAMETERS.items()}

    def configure(self, settings):
        """Sets the named parameters from text; ValueError names a bad or unknown one."""
        values = dict(self.params)
        for name, text in settings.items():
            if name not in self.PARAMETERS:
                raise ValueError('%s: unknown parameter of %s (known: %s)' % (
                    name, type(self).__name__, ', '.join(sorted(self.PARAMETERS)) or 'none'))
            kind, _, check = self.PARAMETERS[name]
            try:
                value = kind(text)
            except ValueError:
                raise ValueError('%s: not a %s: %r' % (name, kind.__name__, text)) from None
            if not check(value):
                raise ValueError('%s: %r is out of range' % (name, value))
            values[name] = value
        self.params = values
        self.configured()

    def configured(self):
        """Called once the parameters are set."""

    def parameter_names(self):
        return sorted(self.PARAMETERS)

    def describe(self):
        return '%s(%s)' % (type(self).__name__, ', '.join(
            '%s=%s' % (name, self.params[name]) for name in sorted(self.params)))
