!> Readers of the groups that describe the body: &geometry, &material and &damping.
module iem_input_body
  use iem_kinds, only: wp
  use iem_constants, only: unset_real
  use iem_strings, only: itoa, rtoa, lower
  use iem_config, only: config_t
  use iem_namelist_text, only: nml_text_t, line_len
  use iem_input_checks, only: bad, check_keys, read_error, check_reals, check_logicals, &
                              check_strings, given
  implicit none
  private
  public :: read_geometry, read_material, read_damping

contains

  ! ----------------------------------------------------------------------------- &geometry
  subroutine parse_geometry(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    real(wp) :: length, height, thickness, cell_size
    integer :: nx, ny
    character(len=8) :: plane, cell
    character(len=256) :: m
    namelist /geometry/ length, height, thickness, nx, ny, cell_size, plane, cell
    length = unset_real; height = unset_real; thickness = cfg%geometry%thickness
    nx = 0; ny = 0; cell_size = 0.0_wp; plane = cfg%geometry%plane; cell = cfg%geometry%cell
    m = ''
    read(chunk, nml=geometry, iostat=ios, iomsg=m)
    iomsg = trim(m)
    cfg%geometry%length = length; cfg%geometry%height = height
    cfg%geometry%thickness = thickness; cfg%geometry%nx = nx; cfg%geometry%ny = ny
    cfg%geometry%cell_size = cell_size; cfg%geometry%plane = lower(plane)
    cfg%geometry%cell = lower(cell)
  end subroutine parse_geometry

  !> Check, parse and validate group g (&geometry) of the input into the configuration.
  subroutine read_geometry(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg
    character(len=*), parameter :: label = '&geometry'
    real(wp) :: nn
    call check_keys(text, g, [character(len=12) :: 'length', 'height', 'thickness', 'nx', 'ny', &
      'cell_size', 'plane', 'cell'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_geometry(chunk, cfg, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, try_geometry, msg)
      stat = 1
      return
    end if
    call check_strings(text, g, label, [character(len=5) :: 'plane', 'cell'], [8, 8], stat, msg)
    if (stat /= 0) return
    if (given(text, g, 'cell_size') .and. .not. (cfg%geometry%cell_size > 0.0_wp)) then
      call bad(label, 'cell_size', rtoa(cfg%geometry%cell_size), 'must be > 0 [m] (or give '// &
               'nx, ny instead)', stat, msg)
      return
    end if
    call check_reals(text, g, label, [character(len=9) :: 'length', 'height', 'thickness', &
      'cell_size'], [cfg%geometry%length, cfg%geometry%height, cfg%geometry%thickness, &
      cfg%geometry%cell_size], stat, msg)
    if (stat /= 0) return
    associate(o => cfg%geometry)
      if (o%length == unset_real) then
        call bad(label, 'length', '(not given)', 'is required [m]', stat, msg)
      else if (.not. (o%length > 0.0_wp)) then
        call bad(label, 'length', rtoa(o%length), 'must be > 0 [m]', stat, msg)
      else if (o%height == unset_real) then
        call bad(label, 'height', '(not given)', 'is required [m]', stat, msg)
      else if (.not. (o%height > 0.0_wp)) then
        call bad(label, 'height', rtoa(o%height), 'must be > 0 [m]', stat, msg)
      else if (.not. (o%thickness > 0.0_wp)) then
        call bad(label, 'thickness', rtoa(o%thickness), 'must be > 0 [m]', stat, msg)
      else if (o%plane /= 'stress' .and. o%plane /= 'strain') then
        call bad(label, 'plane', "'"//trim(o%plane)//"'", "must be 'stress' or 'strain'", &
                 stat, msg)
      else if (o%cell /= 'paper' .and. o%cell /= 'bending') then
        call bad(label, 'cell', "'"//trim(o%cell)//"'", "must be 'paper' or 'bending'", &
                 stat, msg)
      else if (o%cell_size /= 0.0_wp .and. (o%nx /= 0 .or. o%ny /= 0)) then
        call bad(label, 'cell_size', rtoa(o%cell_size), 'cannot be combined with nx, ny', &
                 stat, msg)
      else if (.not. (o%cell_size >= 0.0_wp)) then
        call bad(label, 'cell_size', rtoa(o%cell_size), 'must be > 0 [m]', stat, msg)
      else if (o%cell_size == 0.0_wp .and. o%nx < 1) then
        call bad(label, 'nx', itoa(o%nx), 'must be >= 1 (or give cell_size)', stat, msg)
      else if (o%cell_size == 0.0_wp .and. o%ny < 1) then
        call bad(label, 'ny', itoa(o%ny), 'must be >= 1 (or give cell_size)', stat, msg)
      end if
      if (stat /= 0) return
      if (o%cell_size > 0.0_wp) then
        ! the counts are found in reals first: nint of a quotient above 2^31 is undefined
        if (max(o%length, o%height)/o%cell_size > 2.0e9_wp) then
          call bad(label, 'cell_size', rtoa(o%cell_size), 'gives '// &
                   rtoa(o%length/o%cell_size)//' x '//rtoa(o%height/o%cell_size)// &
                   ' cells: more than 2e9 along a side', stat, msg)
          return
        end if
        o%nx = max(1, nint(o%length/o%cell_size))
        o%ny = max(1, nint(o%height/o%cell_size))
      end if
      nn = (real(o%nx, wp) + 1.0_wp)*(real(o%ny, wp) + 1.0_wp)
      if (nn > 2.0e9_wp) then
        call bad(label, 'nx*ny', itoa(o%nx)//'*'//itoa(o%ny), &
                 'gives more than 2e9 nodes', stat, msg)
      end if
    end associate
  end subroutine read_geometry

  integer function try_geometry(part) result(ios)
    character(len=line_len), intent(in) :: part(:)
    type(config_t) :: c
    character(len=:), allocatable :: m
    call parse_geometry(part, c, ios, m)
  end function try_geometry

  ! ----------------------------------------------------------------------------- &material
  subroutine parse_material(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    real(wp) :: e, nu, density, tensile_strength, compressive_strength, shear_strength
    logical :: nonlinear
    integer :: history_depth
    character(len=256) :: m
    namelist /material/ e, nu, density, nonlinear, tensile_strength, compressive_strength, &
      shear_strength, history_depth
    e = unset_real; nu = unset_real; density = unset_real
    nonlinear = cfg%materials(1)%nonlinear; history_depth = cfg%materials(1)%history_depth
    tensile_strength = unset_real; compressive_strength = unset_real
    shear_strength = unset_real
    m = ''
    read(chunk, nml=material, iostat=ios, iomsg=m)
    iomsg = trim(m)
    cfg%materials(1)%young = e; cfg%materials(1)%poisson = nu; cfg%materials(1)%density = density
    cfg%materials(1)%nonlinear = nonlinear; cfg%materials(1)%history_depth = history_depth
    cfg%materials(1)%tensile_strength = tensile_strength
    cfg%materials(1)%compressive_strength = compressive_strength
    cfg%materials(1)%shear_strength = shear_strength
  end subroutine parse_material

  !> Check, parse and validate group g (&material) of the input into the configuration.
  subroutine read_material(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg
    character(len=*), parameter :: label = '&material'
    call check_keys(text, g, [character(len=20) :: 'e', 'nu', 'density', 'nonlinear', &
      'tensile_strength', 'compressive_strength', 'shear_strength', 'history_depth'], label, &
      stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_material(chunk, cfg, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, try_material, msg)
      stat = 1
      return
    end if
    associate(m => cfg%materials(1))
      call check_reals(text, g, label, [character(len=20) :: 'e', 'nu', 'density', &
        'tensile_strength', 'compressive_strength', 'shear_strength'], [m%young, m%poisson, &
        m%density, m%tensile_strength, m%compressive_strength, m%shear_strength], stat, msg)
    end associate
    if (stat == 0) call check_logicals(text, g, label, ['nonlinear'], stat, msg)
    if (stat /= 0) return
    associate(m => cfg%materials(1))
      if (m%young == unset_real) then
        call bad(label, 'E', '(not given)', "is required: Young's modulus [Pa]", stat, msg)
      else if (.not. (m%young > 0.0_wp)) then
        call bad(label, 'E', rtoa(m%young), 'must be > 0 [Pa]', stat, msg)
      else if (m%poisson == unset_real) then
        call bad(label, 'nu', '(not given)', "is required: Poisson's ratio", stat, msg)
      else if (.not. (m%poisson > -1.0_wp .and. m%poisson < 0.5_wp)) then
        call bad(label, 'nu', rtoa(m%poisson), 'must be in (-1, 0.5)', stat, msg)
      else if (m%density == unset_real) then
        call bad(label, 'density', '(not given)', 'is required [kg/m^3]', stat, msg)
      else if (.not. (m%density > 0.0_wp)) then
        call bad(label, 'density', rtoa(m%density), 'must be > 0 [kg/m^3]', stat, msg)
      else if (m%nonlinear) then
        call check_strength('tensile_strength', m%tensile_strength)
        if (stat == 0) call check_strength('compressive_strength', m%compressive_strength)
        if (stat == 0) call check_strength('shear_strength', m%shear_strength)
        if (stat == 0 .and. m%history_depth < 2) call bad(label, 'history_depth', &
          itoa(m%history_depth), 'must be >= 2 (reversal points kept per spring)', stat, msg)
      else
        ! strengths without nonlinear = .true. would be silently ignored
        if (m%tensile_strength /= unset_real) then
          call bad(label, 'tensile_strength', rtoa(m%tensile_strength), &
                   'is used only with nonlinear = .true.', stat, msg)
        else if (m%compressive_strength /= unset_real) then
          call bad(label, 'compressive_strength', rtoa(m%compressive_strength), &
                   'is used only with nonlinear = .true.', stat, msg)
        else if (m%shear_strength /= unset_real) then
          call bad(label, 'shear_strength', rtoa(m%shear_strength), &
                   'is used only with nonlinear = .true.', stat, msg)
        end if
      end if
    end associate
  contains
    subroutine check_strength(name, value)
      character(len=*), intent(in) :: name
      real(wp), intent(in) :: value
      if (value == unset_real) then
        call bad(label, name, '(not given)', 'is required with nonlinear = .true. [Pa]', stat, msg)
      else if (.not. (value > 0.0_wp)) then
        call bad(label, name, rtoa(value), 'must be > 0 [Pa]', stat, msg)
      end if
    end subroutine check_strength
  end subroutine read_material

  integer function try_material(part) result(ios)
    character(len=line_len), intent(in) :: part(:)
    type(config_t) :: c
    character(len=:), allocatable :: m
    call parse_material(part, c, ios, m)
  end function try_material

  ! ------------------------------------------------------------------------------ &damping
  subroutine parse_damping(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    character(len=12) :: kind
    real(wp) :: ratio, frequency, alpha, beta
    character(len=256) :: m
    real(wp) :: cap_frequency
    namelist /damping/ kind, ratio, frequency, alpha, beta, cap_frequency
    kind = 'none'; ratio = unset_real; frequency = unset_real
    alpha = unset_real; beta = unset_real; cap_frequency = unset_real
    m = ''
    read(chunk, nml=damping, iostat=ios, iomsg=m)
    iomsg = trim(m)
    cfg%damping%kind = lower(kind); cfg%damping%ratio = ratio
    cfg%damping%frequency = frequency; cfg%damping%alpha = alpha; cfg%damping%beta = beta
    cfg%damping%cap_frequency = cap_frequency
  end subroutine parse_damping

  !> Check, parse and validate group g (&damping) of the input into the configuration.
  subroutine read_damping(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg
    character(len=*), parameter :: label = '&damping'
    real(wp) :: omega
    logical :: by_ratio, by_coeff
    call check_keys(text, g, [character(len=13) :: 'kind', 'ratio', 'frequency', 'alpha', &
      'beta', 'cap_frequency'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_damping(chunk, cfg, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, try_damping, msg)
      stat = 1
      return
    end if
    call check_strings(text, g, label, ['kind'], [12], stat, msg)
    if (stat /= 0) return
    associate(d => cfg%damping)
      call check_reals(text, g, label, [character(len=13) :: 'ratio', 'frequency', 'alpha', &
        'beta', 'cap_frequency'], [d%ratio, d%frequency, d%alpha, d%beta, d%cap_frequency], &
        stat, msg)
    end associate
    if (stat /= 0) return
    associate(d => cfg%damping)
      by_ratio = d%ratio /= unset_real .or. d%frequency /= unset_real
      by_coeff = d%alpha /= unset_real .or. d%beta /= unset_real
      select case (trim(d%kind))
      case ('none')
        if (by_ratio .or. by_coeff) call bad(label, 'kind', "'none'", &
          'takes no ratio, frequency, alpha or beta', stat, msg)
      case ('mass', 'stiffness', 'rayleigh', 'capped')
        if (trim(d%kind) /= 'capped' .and. d%cap_frequency /= unset_real) then
          call bad(label, 'cap_frequency', rtoa(d%cap_frequency), &
                   "needs kind = 'capped'", stat, msg)
        else if (trim(d%kind) == 'capped' .and. d%cap_frequency == unset_real) then
          call bad(label, 'cap_frequency', '(not given)', &
                   "is required for kind = 'capped' [Hz]", stat, msg)
        else if (trim(d%kind) == 'capped' .and. .not. (d%cap_frequency > 0.0_wp)) then
          call bad(label, 'cap_frequency', rtoa(d%cap_frequency), 'must be > 0 [Hz]', &
                   stat, msg)
        else if (by_coeff .and. trim(d%kind) /= 'rayleigh') then
          call bad(label, 'kind', "'"//trim(d%kind)//"'", &
                   "is given by ratio and frequency; alpha, beta need kind = 'rayleigh'", stat, msg)
        else if (by_coeff .and. by_ratio) then
          call bad(label, 'alpha', rtoa(d%alpha), &
                   'give either ratio and frequency, or alpha and beta, not both', stat, msg)
        else if (by_coeff) then
          if (d%alpha == unset_real) d%alpha = 0.0_wp
          if (d%beta == unset_real) d%beta = 0.0_wp
          if (.not. (d%alpha >= 0.0_wp)) then
            call bad(label, 'alpha', rtoa(d%alpha), 'must be >= 0 [1/s]', stat, msg)
          else if (.not. (d%beta >= 0.0_wp)) then
            call bad(label, 'beta', rtoa(d%beta), 'must be >= 0 [s]', stat, msg)
          end if
        else if (d%ratio == unset_real) then
          call bad(label, 'ratio', '(not given)', 'is required for kind = '''// &
                   trim(d%kind)//'''', stat, msg)
        else if (.not. (d%ratio >= 0.0_wp .and. d%ratio < 1.0_wp)) then
          call bad(label, 'ratio', rtoa(d%ratio), 'must be in [0, 1)', stat, msg)
        else if (d%frequency == unset_real) then
          call bad(label, 'frequency', '(not given)', 'is required with ratio [Hz]', stat, msg)
        else if (.not. (d%frequency > 0.0_wp)) then
          call bad(label, 'frequency', rtoa(d%frequency), 'must be > 0 [Hz]', stat, msg)
        else
          omega = 2.0_wp*3.141592653589793_wp*d%frequency
          select case (trim(d%kind))
          case ('mass')
            d%alpha = 2.0_wp*d%ratio*omega; d%beta = 0.0_wp
          case ('stiffness')
            d%alpha = 0.0_wp; d%beta = 2.0_wp*d%ratio/omega
          case ('rayleigh')
            d%alpha = d%ratio*omega; d%beta = d%ratio/omega
          case ('capped')
            ! beta follows from ratio, frequency and cap_frequency in the model
            d%alpha = 0.0_wp; d%beta = 0.0_wp
          end select
        end if
      case default
        call bad(label, 'kind', "'"//trim(d%kind)//"'", &
                 "must be 'none', 'mass', 'stiffness', 'rayleigh' or 'capped'", stat, msg)
      end select
      if (d%kind == 'none') then
        d%alpha = 0.0_wp; d%beta = 0.0_wp
      end if
      if (d%ratio == unset_real) d%ratio = 0.0_wp
      if (d%frequency == unset_real) d%frequency = 0.0_wp
      if (d%cap_frequency == unset_real) d%cap_frequency = 0.0_wp
    end associate
  end subroutine read_damping

  integer function try_damping(part) result(ios)
    character(len=line_len), intent(in) :: part(:)
    type(config_t) :: c
    character(len=:), allocatable :: m
    call parse_damping(part, c, ios, m)
  end function try_damping

end module iem_input_body
